//! A job's progress as an indicatif bar on standard error.

/// The bar a job reports to ([`adwi_jobs::Progress`]); hidden with `--quiet`.
pub struct Bar(indicatif::ProgressBar);

impl Bar {
    pub fn new(quiet: bool) -> Bar {
        let bar = if quiet {
            indicatif::ProgressBar::hidden()
        } else {
            indicatif::ProgressBar::new(0)
        };
        if let Ok(style) =
            indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len}, {eta} left")
        {
            bar.set_style(style.progress_chars("=> "));
        }
        Bar(bar)
    }

    /// Clears the bar once the job is done.
    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl adwi_jobs::Progress for Bar {
    fn stage(&self, name: &str, units: Option<u64>) {
        self.0.set_message(name.to_string());
        self.0.set_position(0);
        self.0.set_length(units.unwrap_or(0));
    }

    fn advance(&self, units: u64) {
        self.0.inc(units);
    }
}
