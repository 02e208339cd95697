//! The log tail of one task attempt: the last lines a worker logged while running it, kept in a bounded
//! buffer so a chatty or stuck task cannot grow the worker's memory or the coordinator's queue file, and sent
//! back with the attempt's final event so `crease logs` works after the worker is gone.
//!
//! Lines arrive two ways: directly ([`LogTail::record`], for stage and progress messages that exist even
//! without a log subscriber, as in local single-node mode) and through [`TailLayer`], which copies every
//! `tracing` event emitted inside a span registered with [`capture`] into that span's tail.

use std::collections::{HashMap, VecDeque};
use std::fmt::Write as _;
use std::sync::{Arc, LazyLock, Mutex, MutexGuard};
use tracing::field::{Field, Visit};
use tracing::span::Id;
use tracing::{Event, Span, Subscriber};
use tracing_subscriber::layer::Context;
use tracing_subscriber::registry::LookupSpan;
use tracing_subscriber::Layer;

/// Name of the span a worker opens around one task attempt; log formatters leave it out of their lines
/// (every event in it carries the ids as its own fields) and [`TailLayer`] feeds its tail.
pub const TASK_SPAN: &str = "task";

/// Lines kept per attempt.
pub const MAX_LINES: usize = 200;
/// Bytes kept per line; longer lines are cut at a character boundary and marked with `…`.
pub const MAX_LINE_BYTES: usize = 1024;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A bounded buffer of the most recent lines.
pub struct LogTail {
    max_lines: usize,
    max_line_bytes: usize,
    inner: Mutex<(VecDeque<String>, usize)>,
}

impl Default for LogTail {
    fn default() -> Self {
        LogTail::new(MAX_LINES, MAX_LINE_BYTES)
    }
}

impl LogTail {
    pub fn new(max_lines: usize, max_line_bytes: usize) -> Self {
        LogTail {
            max_lines: max_lines.max(1),
            max_line_bytes: max_line_bytes.max(8),
            inner: Mutex::new((VecDeque::new(), 0)),
        }
    }

    /// Appends a line as is (cut to the line limit); the oldest line goes when the buffer is full.
    pub fn push(&self, line: &str) {
        let line = cut(line, self.max_line_bytes);
        let mut g = lock(&self.inner);
        if g.0.len() == self.max_lines {
            g.0.pop_front();
            g.1 += 1;
        }
        g.0.push_back(line);
    }

    /// Appends `message` stamped with the UTC time of day and a level, the same shape as [`TailLayer`] lines.
    pub fn record(&self, level: &str, message: &str) {
        self.push(&stamp(level, message));
    }

    /// The kept lines, oldest first; when lines were dropped, a first line says how many.
    pub fn lines(&self) -> Vec<String> {
        let g = lock(&self.inner);
        let mut v = Vec::with_capacity(g.0.len() + 1);
        if g.1 > 0 {
            v.push(format!("… {} earlier line(s) dropped", g.1));
        }
        v.extend(g.0.iter().cloned());
        v
    }
}

fn cut(line: &str, max: usize) -> String {
    if line.len() <= max {
        return line.to_string();
    }
    let mut end = max.saturating_sub('…'.len_utf8());
    while !line.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}…", &line[..end])
}

/// `HH:MM:SS.mmm SOURCE message`: one log line as `crease logs` shows it (`source` is a level or
/// `coordinator`).
pub fn stamp(source: &str, message: &str) -> String {
    format!("{} {source:<5} {message}", clock())
}

/// Time of day in UTC, `HH:MM:SS.mmm` (dates are in the attempt header).
fn clock() -> String {
    let d = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    let s = d.as_secs() % 86_400;
    format!(
        "{:02}:{:02}:{:02}.{:03}",
        s / 3600,
        s / 60 % 60,
        s % 60,
        d.subsec_millis()
    )
}

static TAILS: LazyLock<Mutex<HashMap<Id, Arc<LogTail>>>> =
    LazyLock::new(|| Mutex::new(HashMap::new()));

/// While alive, events inside `span` (and its children) are copied into its tail.
pub struct Capture {
    id: Option<Id>,
}

impl Drop for Capture {
    fn drop(&mut self) {
        if let Some(id) = self.id.take() {
            lock(&TAILS).remove(&id);
        }
    }
}

/// Registers `tail` for `span`. Without a subscriber the span has no id and nothing is captured (the direct
/// [`LogTail::record`] lines still are).
pub fn capture(span: &Span, tail: Arc<LogTail>) -> Capture {
    let id = span.id();
    if let Some(id) = &id {
        lock(&TAILS).insert(id.clone(), tail);
    }
    Capture { id }
}

/// The `tracing` layer that feeds the tails of captured spans. Install it beside the log formatter.
pub struct TailLayer;

impl<S> Layer<S> for TailLayer
where
    S: Subscriber + for<'a> LookupSpan<'a>,
{
    fn on_event(&self, event: &Event<'_>, ctx: Context<'_, S>) {
        let Some(scope) = ctx.event_scope(event) else {
            return;
        };
        let tails = lock(&TAILS);
        if tails.is_empty() {
            return;
        }
        for span in scope {
            if let Some(tail) = tails.get(&span.id()) {
                let mut v = LineVisitor::default();
                event.record(&mut v);
                tail.record(event.metadata().level().as_str(), &v.finish());
                return;
            }
        }
    }
}

/// Formats an event as `message key=value ...`, leaving out the ids the attempt header already names.
#[derive(Default)]
struct LineVisitor {
    message: String,
    fields: String,
}

impl LineVisitor {
    fn finish(self) -> String {
        if self.fields.is_empty() {
            self.message
        } else if self.message.is_empty() {
            self.fields.trim_start().to_string()
        } else {
            format!("{}{}", self.message, self.fields)
        }
    }
}

impl Visit for LineVisitor {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        match field.name() {
            "message" => self.message = format!("{value:?}"),
            "job_id" | "task" | "attempt" => {}
            name => {
                let _ = write!(self.fields, " {name}={value:?}");
            }
        }
    }

    fn record_str(&mut self, field: &Field, value: &str) {
        match field.name() {
            "message" => self.message = value.to_string(),
            "job_id" | "task" | "attempt" => {}
            name => {
                let _ = write!(self.fields, " {name}={value}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tracing_subscriber::layer::SubscriberExt;

    #[test]
    fn keeps_the_last_lines_and_says_how_many_were_dropped() {
        let t = LogTail::new(3, 100);
        for i in 0..5 {
            t.push(&format!("line {i}"));
        }
        assert_eq!(
            t.lines(),
            vec!["… 2 earlier line(s) dropped", "line 2", "line 3", "line 4"]
        );
        let t = LogTail::new(3, 100);
        t.push("only");
        assert_eq!(t.lines(), vec!["only"]);
    }

    #[test]
    fn long_lines_are_cut_at_a_character_boundary() {
        let t = LogTail::new(10, 16);
        t.push("ééééééééééééééééééééé");
        t.push("short");
        let lines = t.lines();
        assert!(lines[0].len() <= 16, "{:?}", lines[0]);
        assert!(lines[0].ends_with('…'), "{:?}", lines[0]);
        assert!(lines[0].starts_with("ééé"), "{:?}", lines[0]);
        assert_eq!(lines[1], "short");
    }

    #[test]
    fn events_inside_a_captured_span_reach_its_tail_and_others_do_not() {
        let subscriber = tracing_subscriber::registry().with(TailLayer);
        tracing::subscriber::with_default(subscriber, || {
            let tail = Arc::new(LogTail::new(10, 200));
            let span = tracing::info_span!("task", job_id = "job-1", task = "t");
            let guard = capture(&span, Arc::clone(&tail));
            span.in_scope(|| {
                tracing::info!(job_id = "job-1", worker = "w1", "started");
                let inner = tracing::info_span!("inner");
                inner.in_scope(|| tracing::warn!("nested"));
            });
            tracing::info!("outside");
            drop(guard);
            span.in_scope(|| tracing::info!("after the capture ended"));
            let lines = tail.lines();
            assert_eq!(lines.len(), 2, "{lines:?}");
            assert!(lines[0].ends_with("INFO  started worker=w1"), "{lines:?}");
            assert!(lines[1].ends_with("WARN  nested"), "{lines:?}");
        });
    }
}
