//! `crease view`: the dashboard's 3D before/after viewer and report for one folder on this machine, served
//! without a coordinator (the dashboard's own page and handlers, mounted on the folder). See docs/dashboard.md.

use anyhow::{bail, Context, Result};
use clap::Args;
use crease_dashboard::viewer::folder::Folder;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// An output folder of `crease run` or a job (it holds report.json), or any sequence (a folder of OBJ or
    /// PLY frames, OBJ + PC2) to show alone.
    pub folder: PathBuf,
    /// The input the output was made from (default: the one its report.json names).
    #[arg(long)]
    pub input: Option<PathBuf>,
    /// Address to serve on; port 0 picks a free port. Anyone who can reach it sees the folder: keep it on
    /// 127.0.0.1 unless the network is yours.
    #[arg(long, default_value = "127.0.0.1:0")]
    pub listen: SocketAddr,
    /// Open the page in a browser ($BROWSER, else xdg-open or open).
    #[arg(long)]
    pub open: bool,
}

/// How long a browser launcher may take to fail before it is taken to have started the browser.
const LAUNCH_GRACE: Duration = Duration::from_secs(3);

/// The commands tried to open a URL, in order: `$BROWSER` (its first entry; `%s` stands for the URL), then
/// the desktop's opener.
fn launchers() -> Vec<(String, Vec<String>)> {
    let mut out = Vec::new();
    if let Ok(b) = std::env::var("BROWSER") {
        if let Some(first) = b.split(':').map(str::trim).find(|s| !s.is_empty()) {
            let mut words = first.split_whitespace().map(String::from);
            if let Some(cmd) = words.next() {
                out.push((cmd, words.collect()));
            }
        }
    }
    for cmd in ["xdg-open", "open"] {
        out.push((cmd.to_string(), Vec::new()));
    }
    out
}

/// Starts a browser on `url`; an error says what was tried.
fn open_browser(url: &str) -> Result<String> {
    let mut tried = Vec::new();
    for (cmd, args) in launchers() {
        let has_slot = args.iter().any(|a| a.contains("%s"));
        let mut argv: Vec<String> = args.iter().map(|a| a.replace("%s", url)).collect();
        if !has_slot {
            argv.push(url.to_string());
        }
        let child = Command::new(&cmd)
            .args(&argv)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn();
        let mut child = match child {
            Ok(c) => c,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                tried.push(format!("{cmd} (not found)"));
                continue;
            }
            Err(e) => {
                tried.push(format!("{cmd} ({e})"));
                continue;
            }
        };
        let start = Instant::now();
        loop {
            match child.try_wait() {
                Ok(Some(status)) if status.success() => return Ok(cmd),
                Ok(Some(status)) => {
                    tried.push(format!("{cmd} ({status})"));
                    break;
                }
                Ok(None) if start.elapsed() >= LAUNCH_GRACE => return Ok(cmd),
                Ok(None) => std::thread::sleep(Duration::from_millis(50)),
                Err(e) => {
                    tried.push(format!("{cmd} ({e})"));
                    break;
                }
            }
        }
    }
    bail!(
        "--open: no browser could be started (tried {}); set $BROWSER, or open {url} yourself",
        tried.join(", ")
    )
}

pub fn view(a: ViewArgs) -> Result<()> {
    let folder = Folder::open(&a.folder, a.input.as_deref()).map_err(anyhow::Error::msg)?;
    let loc = folder.located().clone();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    rt.block_on(async move {
        let (bound, server) = crease_dashboard::local::serve(folder, a.listen)
            .await
            .with_context(|| format!("--listen {}: cannot serve there", a.listen))?;
        let url = crease_dashboard::local::url(bound);
        let what = match (&loc.input, &loc.output) {
            (Some(i), Some(o)) => format!("{} (input {})", o.display(), i.display()),
            (None, Some(o)) => format!("{} (output alone)", o.display()),
            (Some(i), None) => format!("{} (a sequence alone)", i.display()),
            (None, None) => unreachable!("a folder always has a sequence"),
        };
        println!("crease view: {what}");
        println!("viewer listening on {url}");
        for note in &loc.notes {
            eprintln!("note: {note}");
        }
        if !bound.ip().is_loopback() {
            eprintln!(
                "warning: serving on {bound}, not on this machine alone: anyone who can reach it sees {}",
                a.folder.display()
            );
        }
        if a.open {
            let url2 = url.clone();
            let how = tokio::task::spawn_blocking(move || open_browser(&url2))
                .await
                .context("starting the browser")??;
            println!("opened {url} with {how}");
        }
        tokio::select! {
            r = tokio::signal::ctrl_c() => r.context("waiting for Ctrl-C")?,
            r = server => r.context("the viewer server stopped")?,
        }
        Ok(())
    })
}
