//! Print the viewer's hot-path timings as JSON (what `ocelli bench view` reports):
//! `cargo run --release -p view --example bench [REPEATS]`.

fn main() {
    let repeats = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(200);
    let timings = view::bench::run(repeats);
    match serde_json::to_string_pretty(&timings) {
        Ok(json) => println!("{json}"),
        Err(e) => eprintln!("bench: {e}"),
    }
}
