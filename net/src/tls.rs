//! PEM files for TLS, read and checked when the process starts so a wrong path or a non-PEM file is reported
//! with its flag instead of as a handshake failure later.

use crate::NetError;
use rustls_pki_types::pem::PemObject;
use rustls_pki_types::{CertificateDer, PrivateKeyDer};
use std::path::{Path, PathBuf};
use tonic::transport::{Certificate, ClientTlsConfig, Identity, ServerTlsConfig};

fn read(flag: &'static str, path: &Path) -> Result<Vec<u8>, NetError> {
    std::fs::read(path).map_err(|e| NetError::file(flag, path, format!("cannot read: {e}")))
}

fn check_certs(flag: &'static str, path: &Path, pem: &[u8]) -> Result<(), NetError> {
    let mut n = 0;
    for c in CertificateDer::pem_slice_iter(pem) {
        c.map_err(|e| NetError::file(flag, path, format!("not a PEM certificate file: {e}")))?;
        n += 1;
    }
    if n == 0 {
        return Err(NetError::file(
            flag,
            path,
            "no PEM certificate (-----BEGIN CERTIFICATE-----) in the file",
        ));
    }
    Ok(())
}

/// A server's certificate chain and private key. Debug shows the paths only.
#[derive(Clone)]
pub struct ServerTls {
    pub cert_path: PathBuf,
    pub key_path: PathBuf,
    cert_pem: Vec<u8>,
    key_pem: Vec<u8>,
}

impl std::fmt::Debug for ServerTls {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ServerTls")
            .field("cert", &self.cert_path)
            .field("key", &self.key_path)
            .finish()
    }
}

impl ServerTls {
    /// Reads `--tls-cert` and `--tls-key`.
    pub fn load(cert: &Path, key: &Path) -> Result<Self, NetError> {
        let cert_pem = read("--tls-cert", cert)?;
        check_certs("--tls-cert", cert, &cert_pem)?;
        let key_pem = read("--tls-key", key)?;
        PrivateKeyDer::from_pem_slice(&key_pem).map_err(|e| {
            NetError::file(
                "--tls-key",
                key,
                format!("no PEM private key (PKCS#8, PKCS#1 or SEC1) in the file: {e}"),
            )
        })?;
        Ok(ServerTls {
            cert_path: cert.to_path_buf(),
            key_path: key.to_path_buf(),
            cert_pem,
            key_pem,
        })
    }

    /// Both or neither: one without the other is a configuration error naming the missing flag.
    pub fn from_flags(cert: Option<&Path>, key: Option<&Path>) -> Result<Option<Self>, NetError> {
        match (cert, key) {
            (Some(c), Some(k)) => Ok(Some(ServerTls::load(c, k)?)),
            (None, None) => Ok(None),
            (Some(_), None) => Err(NetError::Config(
                "--tls-cert was given without --tls-key (CREASE_TLS_KEY)".into(),
            )),
            (None, Some(_)) => Err(NetError::Config(
                "--tls-key was given without --tls-cert (CREASE_TLS_CERT)".into(),
            )),
        }
    }

    /// The certificate chain and key as read (PEM), for servers outside tonic (the dashboard's HTTPS).
    pub fn pem(&self) -> (&[u8], &[u8]) {
        (&self.cert_pem, &self.key_pem)
    }

    pub fn config(&self) -> ServerTlsConfig {
        ServerTlsConfig::new().identity(Identity::from_pem(&self.cert_pem, &self.key_pem))
    }
}

/// What a client trusts: a CA (`--tls-ca`) and optionally the name expected in the server's certificate when
/// it differs from the host in the URL (workers are reached by IP but carry one shared name).
#[derive(Clone, Debug)]
pub struct ClientTls {
    pub ca_path: PathBuf,
    ca_pem: Vec<u8>,
    pub domain: Option<String>,
}

impl ClientTls {
    pub fn load(ca: &Path, domain: Option<String>) -> Result<Self, NetError> {
        let ca_pem = read("--tls-ca", ca)?;
        check_certs("--tls-ca", ca, &ca_pem)?;
        Ok(ClientTls {
            ca_path: ca.to_path_buf(),
            ca_pem,
            domain,
        })
    }

    pub fn config(&self) -> ClientTlsConfig {
        let c = ClientTlsConfig::new().ca_certificate(Certificate::from_pem(&self.ca_pem));
        match &self.domain {
            Some(d) => c.domain_name(d.clone()),
            None => c,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_that_are_not_pem_are_refused_with_flag_and_path() {
        let dir = tempfile::tempdir().unwrap();
        let junk = dir.path().join("junk.pem");
        std::fs::write(&junk, "not a certificate\n").unwrap();
        let e = ClientTls::load(&junk, None).unwrap_err().to_string();
        assert!(e.contains("--tls-ca") && e.contains("junk.pem"), "{e}");
        let e = ServerTls::load(&junk, &junk).unwrap_err().to_string();
        assert!(e.contains("--tls-cert") && e.contains("junk.pem"), "{e}");
        let e = ServerTls::from_flags(Some(&junk), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--tls-key"), "{e}");
        let e = ClientTls::load(&dir.path().join("missing.pem"), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--tls-ca") && e.contains("missing.pem"), "{e}");
    }
}
