//! Progress display: indicatif bars on a terminal, plain log lines (at most one per 10% per stage) otherwise,
//! so farm logs stay readable.

use crease_core::progress::Progress;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use std::collections::HashMap;
use std::io::IsTerminal;
use std::sync::Mutex;

pub struct CliProgress {
    bars: Option<MultiProgress>,
    /// `--quiet`: no bars, no stage lines, no informational lines; warnings ([`Progress::note`]) still print.
    quiet: bool,
    state: Mutex<HashMap<String, Stage>>,
}

struct Stage {
    bar: Option<ProgressBar>,
    done: u64,
    total: u64,
    last_logged_decile: u64,
    started: std::time::Instant,
}

impl CliProgress {
    pub fn new(quiet: bool) -> Self {
        let bars = (!quiet && std::io::stderr().is_terminal()).then(MultiProgress::new);
        CliProgress {
            bars,
            quiet,
            state: Mutex::new(HashMap::new()),
        }
    }

    /// Prints an informational line without tearing the bars (nothing with `--quiet`).
    pub fn println(&self, msg: &str) {
        if !self.quiet {
            self.print_always(msg);
        }
    }

    /// Closes a stage that will not complete (a failed or cancelled job): the bar stops where it was and the
    /// log line says why, never "done".
    pub fn abandon(&self, stage: &str, why: &str) {
        let Ok(mut s) = self.state.lock() else { return };
        if let Some(st) = s.remove(stage) {
            match st.bar {
                Some(b) => b.abandon_with_message(why.to_string()),
                None if !self.quiet => eprintln!(
                    "[{stage}] {why} at {}/{} after {:.2}s",
                    st.done,
                    st.total,
                    st.started.elapsed().as_secs_f64()
                ),
                None => {}
            }
        }
    }

    fn print_always(&self, msg: &str) {
        match &self.bars {
            Some(m) => {
                let _ = m.println(msg);
            }
            None => eprintln!("{msg}"),
        }
    }
}

impl Progress for CliProgress {
    fn begin(&self, stage: &str, total: u64) {
        let bar = self.bars.as_ref().map(|m| {
            let b = m.add(ProgressBar::new(total));
            b.set_style(
                ProgressStyle::with_template(
                    "{prefix:>10} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
            );
            b.set_prefix(stage.to_string());
            b
        });
        if bar.is_none() && !self.quiet {
            eprintln!("[{stage}] started: {total} steps");
        }
        if let Ok(mut s) = self.state.lock() {
            s.insert(
                stage.to_string(),
                Stage {
                    bar,
                    done: 0,
                    total,
                    last_logged_decile: 0,
                    started: std::time::Instant::now(),
                },
            );
        }
    }

    fn advance(&self, stage: &str, n: u64) {
        let Ok(mut s) = self.state.lock() else { return };
        let Some(st) = s.get_mut(stage) else { return };
        st.done += n;
        match &st.bar {
            Some(b) => b.inc(n),
            None => {
                let decile = (st.done * 10).checked_div(st.total).unwrap_or(10);
                if decile > st.last_logged_decile && !self.quiet {
                    st.last_logged_decile = decile;
                    eprintln!(
                        "[{stage}] {}/{} ({:.1}s)",
                        st.done,
                        st.total,
                        st.started.elapsed().as_secs_f64()
                    );
                }
            }
        }
    }

    fn end(&self, stage: &str) {
        let Ok(mut s) = self.state.lock() else { return };
        if let Some(st) = s.remove(stage) {
            match st.bar {
                Some(b) => b.finish(),
                None if !self.quiet => eprintln!(
                    "[{stage}] done in {:.2}s",
                    st.started.elapsed().as_secs_f64()
                ),
                None => {}
            }
        }
    }

    fn note(&self, msg: &str) {
        self.print_always(msg);
    }
}
