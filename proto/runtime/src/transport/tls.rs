//! Mutual TLS for the TCP transport: the cluster's certificate authority, one certificate per
//! node, and the rustls configurations both ends of a link use.
//!
//! **Identity.** A node's certificate carries one DNS name, `n{id}.{role}.ocelli`
//! ([`node_name`]), e.g. `n12.camera.ocelli`, and is signed by the cluster's CA. The name, not
//! an address, is what both ends check, with webpki's own name matching: a dialer verifies
//! the listener's certificate against the name of the node it meant to reach (id and role from
//! the scenario), and a listener — after the chain is verified — checks that the certificate
//! is valid for the id and role the peer's `Hello` claims. So a camera's certificate can never
//! pass as a head's, and a certificate of another cluster's CA never chains. Every node
//! certificate allows both client and server use, since heads both dial (the server) and
//! listen (for cameras).
//!
//! **Files.** A node reads a directory holding `ca.pem` (the CA certificate) and
//! `node-{id}.pem` / `node-{id}.key` ([`TlsFiles`]); `ocelli deploy` writes these for each
//! host, `ocelli launch` for its run. The CA's private key never leaves the machine that made
//! it: [`ClusterCa::from_key_pem`] rebuilds the same issuer from it (same name, same key
//! identifier), so certificates issued later chain to the `ca.pem` already installed.

use proto::ids::{NodeId, Role};
use rcgen::{
    BasicConstraints, CertificateParams, DistinguishedName, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer,
    KeyPair, KeyUsagePurpose,
};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer, ServerName};
use rustls::server::WebPkiClientVerifier;
use rustls::{ClientConfig, RootCertStore, ServerConfig};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use thiserror::Error;

/// What went wrong making, reading or using TLS material.
#[derive(Debug, Error)]
pub enum TlsError {
    #[error("{path}: {problem}")]
    File { path: PathBuf, problem: String },
    #[error("certificate generation: {0}")]
    Generate(String),
    #[error("TLS configuration: {0}")]
    Config(String),
}

/// The DNS name a node's certificate carries: `n{id}.{role}.ocelli`.
pub fn node_name(id: NodeId, role: Role) -> String {
    format!("n{}.{role}.ocelli", id.0)
}

fn server_name(id: NodeId, role: Role) -> ServerName<'static> {
    ServerName::try_from(node_name(id, role)).expect("node names are valid DNS names")
}

/// The cluster's certificate authority: issues one certificate per node.
pub struct ClusterCa {
    params: CertificateParams,
    key: KeyPair,
    cert_pem: String,
}

impl std::fmt::Debug for ClusterCa {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClusterCa").finish_non_exhaustive()
    }
}

/// A node's certificate and private key, PEM.
#[derive(Clone)]
pub struct NodeCert {
    pub cert_pem: String,
    pub key_pem: String,
}

impl std::fmt::Debug for NodeCert {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NodeCert").finish_non_exhaustive()
    }
}

fn gen_err(e: rcgen::Error) -> TlsError {
    TlsError::Generate(e.to_string())
}

fn ca_params(cluster: &str) -> CertificateParams {
    let mut p = CertificateParams::default();
    let mut dn = DistinguishedName::new();
    dn.push(DnType::OrganizationName, "Ocelli");
    dn.push(DnType::CommonName, format!("Ocelli cluster CA {cluster}"));
    p.distinguished_name = dn;
    p.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    p.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    // Valid from 2020 for a century: nodes without a real-time clock (a Pi before NTP) must
    // not refuse certificates because their clock says 1970 or because one expired in the
    // field. Trust is ended by replacing the CA, not by expiry.
    p.not_before = rcgen::date_time_ymd(2020, 1, 1);
    p.not_after = rcgen::date_time_ymd(2120, 1, 1);
    p
}

impl ClusterCa {
    /// A new CA (ECDSA P-256) for the cluster named `cluster`.
    ///
    /// # Errors
    /// [`TlsError::Generate`] if the key or certificate cannot be made.
    pub fn generate(cluster: &str) -> Result<ClusterCa, TlsError> {
        let key = KeyPair::generate().map_err(gen_err)?;
        ClusterCa::with_key(cluster, key)
    }

    /// The CA of `cluster` rebuilt from its private key: certificates it issues chain to the
    /// CA certificate made from the same key and name before.
    ///
    /// # Errors
    /// [`TlsError::Generate`] if the key cannot be read.
    pub fn from_key_pem(cluster: &str, key_pem: &str) -> Result<ClusterCa, TlsError> {
        ClusterCa::with_key(cluster, KeyPair::from_pem(key_pem).map_err(gen_err)?)
    }

    fn with_key(cluster: &str, key: KeyPair) -> Result<ClusterCa, TlsError> {
        let params = ca_params(cluster);
        let cert_pem = params.self_signed(&key).map_err(gen_err)?.pem();
        Ok(ClusterCa {
            params,
            key,
            cert_pem,
        })
    }

    pub fn cert_pem(&self) -> &str {
        &self.cert_pem
    }

    /// The CA's private key, PEM. Keep it off the nodes.
    pub fn key_pem(&self) -> String {
        self.key.serialize_pem()
    }

    /// A certificate for node `id` in `role`, with a fresh key.
    ///
    /// # Errors
    /// [`TlsError::Generate`] if the key or certificate cannot be made.
    pub fn issue(&self, id: NodeId, role: Role) -> Result<NodeCert, TlsError> {
        let key = KeyPair::generate().map_err(gen_err)?;
        let mut p = CertificateParams::new(vec![node_name(id, role)]).map_err(gen_err)?;
        let mut dn = DistinguishedName::new();
        dn.push(DnType::OrganizationName, "Ocelli");
        dn.push(DnType::CommonName, format!("ocelli {role} {}", id.0));
        p.distinguished_name = dn;
        p.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        p.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        p.not_before = rcgen::date_time_ymd(2020, 1, 1);
        p.not_after = rcgen::date_time_ymd(2120, 1, 1);
        p.use_authority_key_identifier_extension = true;
        let issuer = Issuer::from_params(&self.params, &self.key);
        let cert = p.signed_by(&key, &issuer).map_err(gen_err)?;
        Ok(NodeCert {
            cert_pem: cert.pem(),
            key_pem: key.serialize_pem(),
        })
    }
}

/// Where a node's TLS files are: `dir/ca.pem`, `dir/node-{id}.pem`, `dir/node-{id}.key`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TlsFiles {
    pub ca: PathBuf,
    pub cert: PathBuf,
    pub key: PathBuf,
}

impl TlsFiles {
    /// The files of node `id` in `dir`.
    pub fn in_dir(dir: &Path, id: NodeId) -> TlsFiles {
        TlsFiles {
            ca: dir.join("ca.pem"),
            cert: dir.join(format!("node-{}.pem", id.0)),
            key: dir.join(format!("node-{}.key", id.0)),
        }
    }

    /// Write `ca` and `node`'s certificate and key here; the key readable by its owner only.
    ///
    /// # Errors
    /// [`TlsError::File`] naming the file that could not be written.
    pub fn write(&self, ca_pem: &str, node: &NodeCert) -> Result<(), TlsError> {
        write_file(&self.ca, ca_pem, 0o644)?;
        write_file(&self.cert, &node.cert_pem, 0o644)?;
        write_file(&self.key, &node.key_pem, 0o600)
    }
}

/// Write `text` to `path` with `mode` (created with it, so a key is never readable by others,
/// not even for a moment).
///
/// # Errors
/// [`TlsError::File`] naming the path.
pub fn write_file(path: &Path, text: &str, mode: u32) -> Result<(), TlsError> {
    use std::io::Write;
    use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
    let err = |e: std::io::Error| TlsError::File {
        path: path.to_path_buf(),
        problem: e.to_string(),
    };
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(err)?;
    }
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(mode)
        .open(path)
        .map_err(err)?;
    f.set_permissions(std::fs::Permissions::from_mode(mode))
        .map_err(err)?;
    f.write_all(text.as_bytes()).map_err(err)
}

/// A node's TLS setup: who it is (certificate chain and key) and whom it trusts (the CA).
/// Cheap to clone.
#[derive(Clone)]
pub struct Tls {
    server: Arc<ServerConfig>,
    client: Arc<ClientConfig>,
}

impl std::fmt::Debug for Tls {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tls").finish_non_exhaustive()
    }
}

fn read(path: &Path) -> Result<Vec<u8>, TlsError> {
    std::fs::read(path).map_err(|e| TlsError::File {
        path: path.to_path_buf(),
        problem: e.to_string(),
    })
}

fn pem_err(path: &Path, what: &str, e: impl std::fmt::Display) -> TlsError {
    TlsError::File {
        path: path.to_path_buf(),
        problem: format!("not a PEM {what}: {e}"),
    }
}

impl Tls {
    /// Load node `id`'s files from `dir` (see [`TlsFiles`]).
    ///
    /// # Errors
    /// [`TlsError::File`] naming a missing or unreadable file, [`TlsError::Config`] if the
    /// key does not fit rustls.
    pub fn load(dir: &Path, id: NodeId) -> Result<Tls, TlsError> {
        let f = TlsFiles::in_dir(dir, id);
        let (ca, cert, key) = (read(&f.ca)?, read(&f.cert)?, read(&f.key)?);
        let ca: Vec<CertificateDer<'static>> = CertificateDer::pem_slice_iter(&ca)
            .collect::<Result<_, _>>()
            .map_err(|e| pem_err(&f.ca, "certificate", e))?;
        let chain: Vec<CertificateDer<'static>> = CertificateDer::pem_slice_iter(&cert)
            .collect::<Result<_, _>>()
            .map_err(|e| pem_err(&f.cert, "certificate", e))?;
        let key = PrivateKeyDer::from_pem_slice(&key).map_err(|e| pem_err(&f.key, "private key", e))?;
        if ca.is_empty() {
            return Err(pem_err(&f.ca, "certificate", "no certificate in the file"));
        }
        if chain.is_empty() {
            return Err(pem_err(&f.cert, "certificate", "no certificate in the file"));
        }
        Tls::new(ca, chain, key)
    }

    /// From PEM text (tests, tools).
    ///
    /// # Errors
    /// [`TlsError::Config`] if the PEM does not parse or the key does not fit.
    pub fn from_pem(ca_pem: &str, node: &NodeCert) -> Result<Tls, TlsError> {
        let cfg = |e: &dyn std::fmt::Display| TlsError::Config(e.to_string());
        let ca = CertificateDer::pem_slice_iter(ca_pem.as_bytes())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| cfg(&e))?;
        let chain = CertificateDer::pem_slice_iter(node.cert_pem.as_bytes())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| cfg(&e))?;
        let key = PrivateKeyDer::from_pem_slice(node.key_pem.as_bytes()).map_err(|e| cfg(&e))?;
        Tls::new(ca, chain, key)
    }

    fn new(
        ca: Vec<CertificateDer<'static>>,
        chain: Vec<CertificateDer<'static>>,
        key: PrivateKeyDer<'static>,
    ) -> Result<Tls, TlsError> {
        let cfg = |e: &dyn std::fmt::Display| TlsError::Config(e.to_string());
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let mut roots = RootCertStore::empty();
        for c in ca {
            roots.add(c).map_err(|e| cfg(&e))?;
        }
        let roots = Arc::new(roots);
        let verifier = WebPkiClientVerifier::builder_with_provider(roots.clone(), provider.clone())
            .build()
            .map_err(|e| cfg(&e))?;
        let server = ServerConfig::builder_with_provider(provider.clone())
            .with_protocol_versions(&[&rustls::version::TLS13])
            .map_err(|e| cfg(&e))?
            .with_client_cert_verifier(verifier)
            .with_single_cert(chain.clone(), key.clone_key())
            .map_err(|e| cfg(&e))?;
        let client = ClientConfig::builder_with_provider(provider)
            .with_protocol_versions(&[&rustls::version::TLS13])
            .map_err(|e| cfg(&e))?
            .with_root_certificates(roots)
            .with_client_auth_cert(chain, key)
            .map_err(|e| cfg(&e))?;
        Ok(Tls {
            server: Arc::new(server),
            client: Arc::new(client),
        })
    }

    pub(crate) fn acceptor(&self) -> tokio_rustls::TlsAcceptor {
        tokio_rustls::TlsAcceptor::from(self.server.clone())
    }

    pub(crate) fn connector(&self) -> tokio_rustls::TlsConnector {
        tokio_rustls::TlsConnector::from(self.client.clone())
    }

    /// The name a dialer requires of the listener `id` in `role`.
    pub(crate) fn expect(id: NodeId, role: Role) -> ServerName<'static> {
        server_name(id, role)
    }
}

/// Whether the (already chain-verified) certificate `cert` names node `id` in `role`.
///
/// # Errors
/// A sentence saying what the certificate does not prove.
pub(crate) fn certifies(cert: &CertificateDer<'_>, id: NodeId, role: Role) -> Result<(), String> {
    let ee = webpki::EndEntityCert::try_from(cert).map_err(|e| format!("unreadable certificate: {e}"))?;
    ee.verify_is_valid_for_subject_name(&server_name(id, role))
        .map_err(|_| format!("the certificate is not {role} {id}'s ({})", node_name(id, role)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_certificate_names_its_node_and_role_only() {
        let ca = ClusterCa::generate("t").unwrap();
        let c = ca.issue(NodeId(12), Role::Camera).unwrap();
        let der = CertificateDer::from_pem_slice(c.cert_pem.as_bytes()).unwrap();
        assert!(certifies(&der, NodeId(12), Role::Camera).is_ok());
        let e = certifies(&der, NodeId(12), Role::Head).unwrap_err();
        assert!(e.contains("n12.head.ocelli"), "{e}");
        assert!(certifies(&der, NodeId(13), Role::Camera).is_err());
        assert!(Tls::from_pem(ca.cert_pem(), &c).is_ok());
    }

    #[test]
    fn a_ca_rebuilt_from_its_key_issues_certificates_that_chain_to_the_old_ca_certificate() {
        let ca = ClusterCa::generate("t").unwrap();
        let again = ClusterCa::from_key_pem("t", &ca.key_pem()).unwrap();
        let node = again.issue(NodeId(2), Role::Head).unwrap();
        let ca_der = CertificateDer::from_pem_slice(ca.cert_pem().as_bytes()).unwrap();
        let node_der = CertificateDer::from_pem_slice(node.cert_pem.as_bytes()).unwrap();
        let anchor = webpki::anchor_from_trusted_cert(&ca_der).unwrap();
        let ee = webpki::EndEntityCert::try_from(&node_der).unwrap();
        let algs = rustls::crypto::ring::default_provider().signature_verification_algorithms;
        ee.verify_for_usage(
            algs.all,
            &[anchor],
            &[],
            rustls::pki_types::UnixTime::since_unix_epoch(std::time::Duration::from_secs(1_800_000_000)),
            webpki::KeyUsage::server_auth(),
            None,
            None,
        )
        .expect("chains to the CA certificate made before");
    }

    #[test]
    fn files_are_written_with_a_private_key_only_its_owner_reads_and_load_back() {
        use std::os::unix::fs::PermissionsExt;
        let dir = std::env::temp_dir().join(format!("ocelli-tls-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let ca = ClusterCa::generate("t").unwrap();
        let files = TlsFiles::in_dir(&dir, NodeId(3));
        files
            .write(ca.cert_pem(), &ca.issue(NodeId(3), Role::Head).unwrap())
            .unwrap();
        let mode = std::fs::metadata(&files.key).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        assert!(Tls::load(&dir, NodeId(3)).is_ok());
        let e = Tls::load(&dir, NodeId(4)).unwrap_err().to_string();
        assert!(e.contains("node-4.pem"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
