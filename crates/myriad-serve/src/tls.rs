//! TLS for `serve --tls-cert CERT.pem --tls-key KEY.pem`: rustls with ring (the crypto the
//! HTTP client already links), TLS 1.2 and 1.3, ALPN offering HTTP/2 and HTTP/1.1. The
//! handshake is bounded by the header timeout like a first request; one that fails ends its
//! connection alone.

use std::path::Path;
use std::sync::Arc;
use tokio_rustls::rustls;
use tokio_rustls::rustls::pki_types::pem::PemObject;
use tokio_rustls::rustls::pki_types::{CertificateDer, PrivateKeyDer};

pub use tokio_rustls::TlsAcceptor;

/// An acceptor for the certificate chain in `cert` and the private key in `key` (PEM); errors
/// name the file.
/// The most bytes of a certificate chain or a key file.
const MAX_PEM: u64 = 1 << 20;

pub fn acceptor(cert: &Path, key: &Path) -> Result<TlsAcceptor, String> {
    // Read with a bound (a chain is a few KB; /dev/urandom never ended).
    let read = |p: &Path| myriad_io::read_small(p, MAX_PEM).map_err(|e| e.to_string());
    let chain = read(cert)?;
    let certs: Vec<CertificateDer<'static>> = (CertificateDer::pem_slice_iter(&chain))
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{}: {e}", cert.display()))?;
    if certs.is_empty() {
        return Err(format!("{}: no certificate in it (PEM)", cert.display()));
    }
    let key = PrivateKeyDer::from_pem_slice(&read(key)?)
        .map_err(|e| format!("{}: {e}", key.display()))?;
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let mut config = rustls::ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| e.to_string())?
        .with_no_client_auth()
        .with_single_cert(certs, key)
        .map_err(|e| format!("{}: {e}", cert.display()))?;
    config.alpn_protocols = vec![b"h2".to_vec(), b"http/1.1".to_vec()];
    Ok(TlsAcceptor::from(Arc::new(config)))
}
