//! The architecture's dependency invariants, checked on the manifests (ARCHITECTURE.md,
//! "Invariants"): a crate cannot use what it does not depend on, so these keep the layering
//! true at compile time.
//! - No node crate depends on the simulated world (`world`), the simulation (`sim`), the lab or
//!   the CLI — a real node can never read where a target truly is — nor on another node crate.
//! - `proto`, the vocabulary, builds neither tokio nor iceoryx2.

use std::path::Path;

/// The names in a manifest's `[dependencies]` table (dev-dependencies are tests' business).
fn dependencies(manifest: &str) -> Vec<String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(manifest);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let doc: toml::Table = toml::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    doc.get("dependencies")
        .and_then(|d| d.as_table())
        .map(|t| t.keys().cloned().collect())
        .unwrap_or_default()
}

#[test]
fn node_crates_never_depend_on_the_simulated_world_or_each_other() {
    let forbidden = [
        "world",
        "sim",
        "lab",
        "deploy",
        "node-camera",
        "node-head",
        "node-server",
        "node-acoustic",
        "view",
    ];
    for krate in ["node-camera", "node-camera/acoustic", "node-head", "node-server"] {
        let deps = dependencies(&format!("{krate}/Cargo.toml"));
        assert!(
            deps.iter().any(|d| d == "proto"),
            "{krate} should depend on proto: {deps:?}"
        );
        for f in forbidden {
            assert!(!deps.iter().any(|d| d == f), "{krate} depends on {f}");
        }
    }
}

#[test]
fn the_vocabulary_builds_no_runtime() {
    let deps = dependencies("proto/Cargo.toml");
    for f in ["tokio", "tokio-util", "iceoryx2", "futures-util", "runtime"] {
        assert!(!deps.iter().any(|d| d == f), "proto depends on {f}: {deps:?}");
    }
    // The simulated world needs only the vocabulary.
    let deps = dependencies("deploy/world/Cargo.toml");
    for f in [
        "runtime",
        "tokio",
        "iceoryx2",
        "node-camera",
        "node-head",
        "node-server",
    ] {
        assert!(!deps.iter().any(|d| d == f), "world depends on {f}: {deps:?}");
    }
}

#[test]
fn the_assignment_crate_stays_a_leaf() {
    // Every node crate may use it, so it must not pull in anything a node may not depend on.
    let deps = dependencies("proto/assign/Cargo.toml");
    assert_eq!(
        deps,
        vec!["pathfinding".to_string()],
        "assign depends on {deps:?}"
    );
}
