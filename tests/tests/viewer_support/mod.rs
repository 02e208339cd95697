//! `crease view` as the viewer tests start it: a real process on a free loopback port, stopped when the test
//! drops it, and the URL it printed.
#![allow(dead_code)]

use crease_e2e::*;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;

/// A running `crease view`: the process, the page URL it printed and the address it serves on.
pub struct View {
    pub proc: Proc,
    pub url: String,
    pub addr: String,
}

/// Starts `crease view FOLDER EXTRA…` on a free port and waits for the URL line.
pub fn view(folder: &Path, extra: &[&str]) -> View {
    let port = free_port();
    let mut child = Command::new(bin())
        .arg("view")
        .arg(folder)
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start crease view");
    let stdout = child.stdout.take().unwrap();
    let proc = Proc(child);
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let url = loop {
        let line = rx
            .recv_timeout(DEADLINE)
            .expect("crease view printed no URL in time");
        if let Some(u) = line.strip_prefix("viewer listening on ") {
            break u.trim().to_string();
        }
    };
    let addr = format!("127.0.0.1:{port}");
    assert!(url.starts_with(&format!("http://{addr}/")), "{url}");
    View { proc, url, addr }
}
