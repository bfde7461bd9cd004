//! Progress of long work on stderr: an `indicatif` bar when stderr is a terminal, plain lines when it
//! is not (a `2>log` run, a cluster job's log), so that a log shows what a run is doing and how far
//! it got (issue 22, item 5: cluster logs stayed empty).
//!
//! Lines come at a sane rate: [`Progress::update`] (called as often as a loop likes, e.g. every 16
//! steps) writes a line at its first call and then at most one per [`line_interval`] (default
//! [`DEFAULT_LINE_SECONDS`] s; the environment variable `TISSUEFIT_PROGRESS_SECONDS` sets another, 0
//! for every update); [`Progress::line`] writes one at once (one per fit evaluation). A
//! [`Heartbeat`] writes such lines from inside work that reports no position of its own (a fit
//! evaluation's relaxation, which may run for minutes), from any thread. `-q` turns the lines off
//! ([`set_quiet`]).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Seconds between two progress lines of [`Progress::update`] by default.
pub const DEFAULT_LINE_SECONDS: f64 = 30.0;

/// The environment variable that sets the seconds between two progress lines.
pub const LINE_SECONDS_VARIABLE: &str = "TISSUEFIT_PROGRESS_SECONDS";

static QUIET: AtomicBool = AtomicBool::new(false);

/// Turns the progress lines (not the bars, which `-q` users on a terminal still see) off or on for
/// this process (`-q`).
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::SeqCst);
}

/// The least time between two lines of [`Progress::update`]: `TISSUEFIT_PROGRESS_SECONDS` when it
/// holds a number ≥ 0 (a warning and the default otherwise), else [`DEFAULT_LINE_SECONDS`].
pub fn line_interval() -> Duration {
    let Ok(text) = std::env::var(LINE_SECONDS_VARIABLE) else {
        return Duration::from_secs_f64(DEFAULT_LINE_SECONDS);
    };
    match text.trim().parse::<f64>() {
        Ok(s) if s.is_finite() && s >= 0.0 => Duration::from_secs_f64(s),
        _ => {
            tracing::warn!(
                "{LINE_SECONDS_VARIABLE}={text:?} is not a number of seconds ≥ 0; progress lines every \
                 {DEFAULT_LINE_SECONDS} s"
            );
            Duration::from_secs_f64(DEFAULT_LINE_SECONDS)
        }
    }
}

/// A progress display: a bar on a terminal, lines otherwise, nothing when disabled.
pub struct Progress {
    bar: ProgressBar,
    /// Write lines (stderr is not a terminal, progress is wanted, not `-q`).
    lines: bool,
    /// What the lines start with, e.g. "simulate tissue.vtp".
    label: String,
    /// Total (steps, evaluations) for the lines.
    len: u64,
    unit: &'static str,
    every: Duration,
    last: Option<Instant>,
    started: Instant,
    /// A caller's listener (the Python API), told of every update whether or not anything is shown.
    watch: Watch,
}

impl Progress {
    /// A display of `len` `unit`s (e.g. "steps") labelled `label`; `template` is the bar's
    /// `indicatif` template. `enabled = false` shows nothing at all.
    pub fn new(label: impl Into<String>, len: u64, unit: &'static str, template: &str, enabled: bool) -> Self {
        let terminal = std::io::stderr().is_terminal();
        let bar = if enabled && terminal {
            let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
            bar.set_style(ProgressStyle::with_template(template).expect("valid template"));
            bar
        } else {
            ProgressBar::hidden()
        };
        Self {
            bar,
            lines: enabled && !terminal && !QUIET.load(Ordering::SeqCst),
            label: label.into(),
            len,
            unit,
            every: line_interval(),
            last: None,
            started: Instant::now(),
            watch: Watch::default(),
        }
    }

    /// Also tells `watch` of every update, line and message (see [`Watch`]).
    pub fn with_watch(mut self, watch: Watch) -> Self {
        self.watch = watch;
        self
    }

    /// A display of a simulation's `len` steps.
    pub fn of_steps(label: impl Into<String>, len: u64, enabled: bool) -> Self {
        Self::new(label, len, "step", "{elapsed_precise} [{wide_bar}] {pos}/{len} steps, {msg}, ETA {eta}", enabled)
    }

    /// A simulation's per-step report ([`crate::mechanics::Observer::progress`]): every 16th step
    /// moves the display, with the residual.
    pub fn step(&mut self, step: u64, residual: f64) {
        if step.is_multiple_of(16) {
            self.update(step, || format!("residual {residual:.3e}"));
        }
    }

    /// Moves to `position`, with `message` (built only when shown) on the bar and in a line when one
    /// is due.
    pub fn update(&mut self, position: u64, message: impl FnOnce() -> String) {
        let due = self.lines && self.last.is_none_or(|t| t.elapsed() >= self.every);
        let heard = self.watch.due();
        if self.bar.is_hidden() && !due && !heard {
            return;
        }
        let message = message();
        if heard {
            self.watch.report(&self.label, position, self.len, self.unit, &message);
        }
        if due {
            self.write(position, &message);
        }
        self.bar.set_position(position);
        self.bar.set_message(message);
    }

    /// Moves to `position` and writes a line now (when lines are on), e.g. after each evaluation.
    pub fn line(&mut self, position: u64, message: &str) {
        if self.lines {
            self.write(position, message);
        }
        self.watch.report(&self.label, position, self.len, self.unit, message);
        self.bar.set_position(position.min(self.len));
        self.bar.set_message(message.to_string());
    }

    /// Sets the bar's message only (no line; a watch hears it at the bar's position).
    pub fn set_message(&self, message: String) {
        self.watch.report(&self.label, self.bar.position(), self.len, self.unit, &message);
        self.bar.set_message(message);
    }

    fn write(&mut self, position: u64, message: &str) {
        // Past the total (a fit's profile evaluations after its budget): the count alone.
        let of = if position <= self.len { format!("/{}", self.len) } else { String::new() };
        eprintln!(
            "{}: {} {position}{of}, {message}; {:.1} s",
            self.label,
            self.unit,
            self.started.elapsed().as_secs_f64()
        );
        self.last = Some(Instant::now());
    }

    /// Removes the bar (lines stay in the log).
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// Lines that say long work is still running, for logs (stderr not a terminal): [`Heartbeat::beat`]
/// may be called as often as a loop likes, from any thread; it writes `LABEL: MESSAGE; T s` when
/// [`line_interval`] has passed since the last line (or since the start: work shorter than that
/// writes nothing). Off on a terminal (the caller's bar shows the progress), with `-q`, or when
/// not enabled.
pub struct Heartbeat {
    label: String,
    on: bool,
    every: Duration,
    started: Instant,
    last: Mutex<Instant>,
}

impl Heartbeat {
    pub fn new(label: impl Into<String>, enabled: bool) -> Self {
        let now = Instant::now();
        Self {
            label: label.into(),
            on: enabled && !std::io::stderr().is_terminal() && !QUIET.load(Ordering::SeqCst),
            every: line_interval(),
            started: now,
            last: Mutex::new(now),
        }
    }

    /// Whether lines are written at all.
    pub fn is_on(&self) -> bool {
        self.on
    }

    /// Writes a line with `message` (built only then) when one is due.
    pub fn beat(&self, message: impl FnOnce() -> String) {
        if !self.on {
            return;
        }
        let Ok(mut last) = self.last.lock() else { return };
        if last.elapsed() < self.every {
            return;
        }
        eprintln!("{}: {}; {:.1} s", self.label, message(), self.started.elapsed().as_secs_f64());
        *last = Instant::now();
    }
}

/// What a [`Watch`] hears: the work (a [`Progress`]'s label, e.g. "fit" or "simulate tissue.vtp"),
/// how far it got in its unit, and the message a bar would show.
#[derive(Clone, Copy, Debug)]
pub struct Report<'a> {
    pub label: &'a str,
    pub done: u64,
    pub total: u64,
    /// "step", "evaluation", "label".
    pub unit: &'a str,
    pub message: &'a str,
}

/// A caller's hold on long work that it does not display itself (the Python API, a napari
/// widget): its listener hears every update of the work's [`Progress`] displays (from the thread
/// doing the work, at most every [`Watch::EVERY`], and every fit evaluation), and the caller can ask
/// the work to stop: a listener that returns `false`, or [`Watch::stop`]. The work looks at
/// [`Watch::stopped`] where it can stop cleanly (a simulation at the end of a step, a fit before
/// and during each evaluation) and ends with its "stopped" error. The default watch hears nothing
/// and never stops.
#[derive(Clone, Default)]
pub struct Watch(Option<Arc<WatchInner>>);

type Listener = Box<dyn Fn(&Report<'_>) -> bool + Send + Sync>;

struct WatchInner {
    listener: Listener,
    stop: AtomicBool,
    last: Mutex<Option<Instant>>,
}

impl std::fmt::Debug for Watch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.0 {
            Some(inner) => write!(f, "Watch(stopped: {})", inner.stop.load(Ordering::SeqCst)),
            None => f.write_str("Watch(none)"),
        }
    }
}

impl Watch {
    /// The least time between two reports of [`Progress::update`] (a fit's per-evaluation lines
    /// always reach the listener).
    pub const EVERY: Duration = Duration::from_millis(200);

    /// A watch whose `listener` returns whether the work may go on.
    pub fn new(listener: impl Fn(&Report<'_>) -> bool + Send + Sync + 'static) -> Self {
        Self(Some(Arc::new(WatchInner {
            listener: Box::new(listener),
            stop: AtomicBool::new(false),
            last: Mutex::new(None),
        })))
    }

    /// Whether anyone listens.
    pub fn is_on(&self) -> bool {
        self.0.is_some()
    }

    /// Asks the work to stop at its next clean point.
    pub fn stop(&self) {
        if let Some(inner) = &self.0 {
            inner.stop.store(true, Ordering::SeqCst);
        }
    }

    /// Whether the work was asked to stop.
    pub fn stopped(&self) -> bool {
        self.0.as_ref().is_some_and(|inner| inner.stop.load(Ordering::SeqCst))
    }

    /// Whether a rate-limited update is due (its message is then worth building).
    fn due(&self) -> bool {
        let Some(inner) = &self.0 else { return false };
        inner.last.lock().map(|last| last.is_none_or(|t| t.elapsed() >= Self::EVERY)).unwrap_or(false)
    }

    /// Tells the listener when a rate-limited report is due ([`Watch::EVERY`]), with `message`
    /// built only then.
    pub fn tick(&self, label: &str, done: u64, total: u64, unit: &str, message: impl FnOnce() -> String) {
        if self.due() {
            self.report(label, done, total, unit, &message());
        }
    }

    /// Tells the listener; its `false` stops the work.
    pub fn report(&self, label: &str, done: u64, total: u64, unit: &str, message: &str) {
        let Some(inner) = &self.0 else { return };
        if let Ok(mut last) = inner.last.lock() {
            *last = Some(Instant::now());
        }
        if !(inner.listener)(&Report { label, done, total, unit, message }) {
            inner.stop.store(true, Ordering::SeqCst);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU64;

    #[test]
    fn a_watch_hears_a_progress_display_and_its_listener_can_stop_the_work() {
        let heard = Arc::new(AtomicU64::new(0));
        let h = heard.clone();
        let watch = Watch::new(move |r| {
            assert_eq!((r.label, r.total, r.unit), ("work", 10, "step"));
            h.fetch_add(1, Ordering::SeqCst);
            r.done < 5
        });
        // A display that shows nothing (no bar, no lines) still tells its watch.
        let mut progress = Progress::new("work", 10, "step", "{pos}", false).with_watch(watch.clone());
        progress.update(1, || "first".into());
        assert_eq!(heard.load(Ordering::SeqCst), 1);
        // Updates closer together than Watch::EVERY are not passed on; lines always are.
        progress.update(2, || panic!("the message of an update nobody hears is not built"));
        assert_eq!(heard.load(Ordering::SeqCst), 1);
        assert!(!watch.stopped());
        progress.line(7, "an evaluation finished");
        assert_eq!(heard.load(Ordering::SeqCst), 2);
        assert!(watch.stopped(), "the listener's false stops the work");
    }

    #[test]
    fn the_default_watch_hears_nothing_and_never_stops() {
        let watch = Watch::default();
        assert!(!watch.is_on());
        watch.report("work", 1, 2, "step", "m");
        watch.tick("work", 1, 2, "step", || panic!("not built"));
        watch.stop();
        assert!(!watch.stopped());
        assert_eq!(format!("{watch:?}"), "Watch(none)");
    }
}
