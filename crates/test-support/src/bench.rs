//! How a benchmark binary (a `harness = false` bench target with `test = true`) runs:
//! measured under `cargo bench`, which passes `--bench`; a smoke run with tiny sizes under
//! `cargo test`, which passes no such flag, so that CI runs every benchmark's code and
//! its table on every change while only `cargo bench` spends the minutes a measurement
//! needs.

/// How this benchmark process runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchRun {
    /// Under `cargo bench`: the documented sizes, timings worth reading.
    Measured,
    /// Under `cargo test`: tiny sizes, the same code and table; timings mean nothing.
    Smoke,
}

impl BenchRun {
    /// From this process's arguments (`--bench` = measured); a smoke run says so on
    /// standard output first.
    pub fn from_args() -> BenchRun {
        let run = BenchRun::from_arguments(std::env::args().skip(1));
        if run == BenchRun::Smoke {
            println!(
                "smoke run (no --bench: `cargo test`): tiny sizes, timings not meaningful; \
                 `cargo bench` measures"
            );
        }
        run
    }

    /// Measured when one of `args` (the process's, without its name) is `--bench`.
    pub fn from_arguments<S: AsRef<str>>(args: impl IntoIterator<Item = S>) -> BenchRun {
        if args.into_iter().any(|a| a.as_ref() == "--bench") {
            BenchRun::Measured
        } else {
            BenchRun::Smoke
        }
    }

    /// `measured` under `cargo bench`, `smoke` under `cargo test`.
    pub fn size<T>(self, measured: T, smoke: T) -> T {
        match self {
            BenchRun::Measured => measured,
            BenchRun::Smoke => smoke,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cargo_bench_measures_and_cargo_test_runs_a_smoke_test() {
        assert_eq!(BenchRun::from_arguments(["--bench"]), BenchRun::Measured);
        assert_eq!(
            BenchRun::from_arguments(["--steps", "9", "--bench"]),
            BenchRun::Measured
        );
        assert_eq!(
            BenchRun::from_arguments(Vec::<String>::new()),
            BenchRun::Smoke
        );
        assert_eq!(BenchRun::from_arguments(["--nocapture"]), BenchRun::Smoke);
        assert_eq!(BenchRun::Measured.size(60_000, 2_000), 60_000);
        assert_eq!(BenchRun::Smoke.size(60_000, 2_000), 2_000);
    }
}
