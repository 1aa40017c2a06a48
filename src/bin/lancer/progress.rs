//! Progress bars on standard error, drawn from what the library reports
//! (the waves of a render, the steps of the bench suite), and only when
//! standard error is a terminal.

use std::cell::RefCell;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lancer::analysis::bench::SuiteProgress;
use lancer::render::{OnWave, WaveProgress};

/// Whether to draw progress bars: standard error is a terminal.
fn wanted() -> bool {
    std::io::IsTerminal::is_terminal(&std::io::stderr())
}

/// A bar of `steps` on stderr drawn with `template` (indicatif's syntax).
fn bar(steps: u64, template: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// The bars of a renderer's calls: one per call of a rendering method,
/// made when the call starts, moved after every wave, cleared after the
/// last.
pub struct Waves(Option<Box<WaveFn>>);

/// What watches a render's waves.
type WaveFn = dyn Fn(WaveProgress);

impl Waves {
    /// Bars when standard error is a terminal, else none.
    pub fn new() -> Waves {
        Waves(wanted().then(|| {
            let current: RefCell<Option<ProgressBar>> = RefCell::new(None);
            Box::new(move |p: WaveProgress| {
                let mut slot = current.borrow_mut();
                if p.done == 0 {
                    *slot = Some(bar(
                        p.total,
                        "{spinner} rendering [{bar:30}] wave {pos}/{len} {elapsed_precise} eta {eta}",
                    ));
                }
                if let Some(b) = slot.as_ref() {
                    b.set_position(p.done);
                    if p.done >= p.total {
                        b.finish_and_clear();
                        *slot = None;
                    }
                }
            }) as Box<WaveFn>
        }))
    }

    /// What the rendering methods take.
    pub fn observer(&self) -> OnWave<'_> {
        self.0.as_deref()
    }
}

/// The bar of `lancer bench`'s suite: its steps, and what each does.
pub struct Suite(Option<Box<SuiteFn>>);

/// What watches the bench suite's steps.
type SuiteFn = dyn Fn(SuiteProgress);

impl Suite {
    /// A bar when standard error is a terminal, else none.
    pub fn new() -> Suite {
        Suite(wanted().then(|| {
            let current: RefCell<Option<ProgressBar>> = RefCell::new(None);
            Box::new(move |p: SuiteProgress| {
                let mut slot = current.borrow_mut();
                let b = slot.get_or_insert_with(|| {
                    bar(
                        p.total,
                        "{spinner} bench [{bar:30}] {pos}/{len} {elapsed_precise} {msg}",
                    )
                });
                b.set_position(p.done);
                b.set_message(p.doing.to_string());
                if p.done >= p.total {
                    b.finish_and_clear();
                }
            }) as Box<SuiteFn>
        }))
    }

    /// What [`lancer::analysis::bench::run_suite`] takes.
    pub fn observer(&self) -> Option<&SuiteFn> {
        self.0.as_deref()
    }
}
