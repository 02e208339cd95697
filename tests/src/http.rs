//! The HTTP side of a running process: a plain HTTP/1.1 GET (metrics, health probes) and the address a
//! process logged for its metrics server.

use crate::process::wait_until;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::Duration;

/// `GET path` on `addr`: (status code, body); None when nothing answers.
pub fn http_get(addr: &str, path: &str) -> Option<(u16, String)> {
    let mut s = TcpStream::connect(addr).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(10))).ok()?;
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut buf = String::new();
    s.read_to_string(&mut buf).ok()?;
    let code = buf.split_whitespace().nth(1)?.parse().ok()?;
    let body = buf.split_once("\r\n\r\n").map(|(_, b)| b.to_string())?;
    Some((code, body))
}

/// [`http_get`], failing the test when nothing answers.
pub fn get(addr: &str, path: &str) -> (u16, String) {
    http_get(addr, path).unwrap_or_else(|| panic!("no answer from http://{addr}{path}"))
}

/// The `host:port` after "metrics listening on " in a process's log, once it is there.
pub fn metrics_addr(log: &Path) -> String {
    let mut addr = String::new();
    wait_until(&format!("metrics address in {}", log.display()), || {
        let text = std::fs::read_to_string(log).unwrap_or_default();
        match text.split("metrics listening on ").nth(1) {
            Some(rest) => {
                addr = rest
                    .chars()
                    .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == ':')
                    .collect();
                true
            }
            None => false,
        }
    });
    addr
}
