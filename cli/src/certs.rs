//! `crease certs`: a development CA with a coordinator and a worker certificate, so TLS can be tried and
//! tested without an outside PKI. Production clusters should use their own CA (e.g. cert-manager); the file
//! names are the ones the deploy manifests and the tests expect.

use anyhow::{Context, Result};
use clap::Args;
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct CertsArgs {
    /// Directory for ca.pem, coordinator.pem/.key and worker.pem/.key (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Extra name (DNS name or IP) in the coordinator certificate, besides localhost, 127.0.0.1 and
    /// crease-coordinator. Repeatable.
    #[arg(long = "coordinator-name")]
    pub coordinator_names: Vec<String>,
    /// Name in the worker certificate (what the coordinator expects: its --worker-tls-domain).
    #[arg(long = "worker-name", default_value = "crease-worker")]
    pub worker_name: String,
}

pub fn certs(a: CertsArgs) -> Result<()> {
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("--out {}: cannot create the directory", a.out.display()))?;
    let mut ca_params = CertificateParams::new(Vec::<String>::new())?;
    ca_params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    ca_params
        .distinguished_name
        .push(DnType::CommonName, "crease development CA");
    ca_params.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::CrlSign,
        KeyUsagePurpose::DigitalSignature,
    ];
    let ca_key = KeyPair::generate().context("generating the CA key")?;
    let ca_cert = ca_params.self_signed(&ca_key).context("signing the CA")?;
    let issuer = Issuer::new(ca_params, ca_key);

    let mut coordinator_names: Vec<String> = ["localhost", "127.0.0.1", "crease-coordinator"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    for n in a.coordinator_names {
        if !coordinator_names.contains(&n) {
            coordinator_names.push(n);
        }
    }
    write(&a.out, "ca.pem", &ca_cert.pem(), false)?;
    leaf(&a.out, "coordinator", coordinator_names, &issuer)?;
    leaf(&a.out, "worker", vec![a.worker_name], &issuer)?;
    eprintln!(
        "wrote ca.pem, coordinator.pem, coordinator.key, worker.pem, worker.key to {}",
        a.out.display()
    );
    Ok(())
}

/// A server certificate (also usable as a client certificate) for `names`, signed by `issuer`.
fn leaf(dir: &Path, file: &str, names: Vec<String>, issuer: &Issuer<'_, KeyPair>) -> Result<()> {
    let mut params = CertificateParams::new(names.clone())
        .with_context(|| format!("{file} certificate names {names:?}"))?;
    params
        .distinguished_name
        .push(DnType::CommonName, names[0].as_str());
    params.use_authority_key_identifier_extension = true;
    params.key_usages = vec![
        KeyUsagePurpose::DigitalSignature,
        KeyUsagePurpose::KeyEncipherment,
    ];
    params.extended_key_usages = vec![
        ExtendedKeyUsagePurpose::ServerAuth,
        ExtendedKeyUsagePurpose::ClientAuth,
    ];
    let key = KeyPair::generate().with_context(|| format!("generating the {file} key"))?;
    let cert = params
        .signed_by(&key, issuer)
        .with_context(|| format!("signing the {file} certificate"))?;
    write(dir, &format!("{file}.pem"), &cert.pem(), false)?;
    write(dir, &format!("{file}.key"), &key.serialize_pem(), true)
}

/// Writes a file; private keys are created with mode 0600 (never world-readable, not even briefly).
fn write(dir: &Path, name: &str, text: &str, private: bool) -> Result<()> {
    use std::io::Write;
    let path = dir.join(name);
    let mut opts = std::fs::OpenOptions::new();
    opts.write(true).create(true).truncate(true);
    #[cfg(unix)]
    if private {
        use std::os::unix::fs::OpenOptionsExt;
        opts.mode(0o600);
    }
    let mut f = opts
        .open(&path)
        .with_context(|| format!("writing {}", path.display()))?;
    #[cfg(unix)]
    if private {
        // An existing file keeps its old mode through `open`: tighten it.
        use std::os::unix::fs::PermissionsExt;
        f.set_permissions(std::fs::Permissions::from_mode(0o600))
            .with_context(|| format!("chmod 600 {}", path.display()))?;
    }
    f.write_all(text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
