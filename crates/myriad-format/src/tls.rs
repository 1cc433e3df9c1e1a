//! The certificates `https://` requests trust, shared by the two kinds of requests this crate
//! makes: datasets read by range requests ([`crate::remote::HttpBytes`]) and whole objects
//! copied to and from S3 ([`crate::s3::Client`]). `MYRIAD_CA_CERT` names a PEM file whose
//! certificates (a server's own, self-signed one) are then the only ones trusted; without it,
//! Mozilla's roots are.

/// The certificates `https://` trusts: those of `MYRIAD_CA_CERT` where it names a PEM file,
/// else Mozilla's.
pub(crate) fn trusted() -> std::result::Result<ureq::tls::TlsConfig, String> {
    use ureq::tls::{PemItem, RootCerts, TlsConfig};
    let Ok(file) = std::env::var("MYRIAD_CA_CERT") else {
        return Ok(TlsConfig::default());
    };
    // A bundle of every root is about 200 KB.
    let pem = myriad_io::read_small(std::path::Path::new(&file), 16 << 20)
        .map_err(|e| format!("MYRIAD_CA_CERT: {e}"))?;
    let mut certs = Vec::new();
    for item in ureq::tls::parse_pem(&pem) {
        match item {
            Ok(PemItem::Certificate(c)) => certs.push(c.to_owned()),
            Ok(_) => {}
            Err(e) => return Err(format!("MYRIAD_CA_CERT {file}: {e}")),
        }
    }
    if certs.is_empty() {
        return Err(format!("MYRIAD_CA_CERT {file}: no certificate in it"));
    }
    Ok(TlsConfig::builder()
        .root_certs(RootCerts::Specific(std::sync::Arc::new(certs)))
        .build())
}
