//! The old spellings of renamed flags and values, kept as hidden aliases for one release:
//! each still parses, and [`warnings`] names its new spelling.

/// One old spelling: the subcommand, the old flag, the old value (`None`: any), and the
/// new spelling.
#[derive(Clone, Copy, Debug)]
pub struct Renamed {
    /// The subcommand whose flag was renamed.
    pub command: &'static str,
    /// The old flag, with its dashes (`--model`).
    pub old: &'static str,
    /// The old value of the flag, when only a value was renamed.
    pub value: Option<&'static str>,
    /// What to write instead.
    pub new: &'static str,
}

const fn r(command: &'static str, old: &'static str, new: &'static str) -> Renamed {
    Renamed {
        command,
        old,
        value: None,
        new,
    }
}

/// Every old spelling still accepted.
pub const RENAMED: &[Renamed] = &[
    r("evaluate", "--model", "--network"),
    r("export", "--model", "--network"),
    r("export", "--accuracy-json", "--report"),
    r("sil", "--lstm", "--network"),
    r("sil", "--model", "--identified"),
    r("sil", "--json", "--report"),
    r("sil", "--markdown", "--report-md"),
    r("import", "--torch", "--network"),
    r("torque", "--model", "--identified"),
    r("torque", "--output", "--out"),
    r("identify", "--output", "--out"),
    r("identify", "--validate", "--validation-log"),
    r("simulate", "--output", "--out"),
    r("simulate", "--locked-rad", "--lock J=RAD,..."),
    r("excite", "--out-dir", "--out"),
    r("identify", "--drive-gains", "--torque-constants"),
    r("torque", "--drive-gains", "--torque-constants"),
    r(
        "train",
        "--paper-output",
        "--preset paper (next) or --preset paper_relative (relative)",
    ),
    r(
        "evaluate",
        "--paper-output",
        "--preset paper (next) or --preset paper_relative (relative)",
    ),
    r("identify", "--friction-model", "--friction"),
    r("torque", "--friction-model", "--friction"),
    Renamed {
        command: "identify",
        old: "--friction",
        value: Some("paper"),
        new: "--friction viscous-coulomb",
    },
    Renamed {
        command: "torque",
        old: "--friction",
        value: Some("paper"),
        new: "--friction viscous-coulomb",
    },
];

/// The warnings for the old spellings in a command line (the arguments after the
/// program name), one line each.
pub fn warnings<S: AsRef<str>>(args: &[S]) -> Vec<String> {
    let args: Vec<&str> = args.iter().map(AsRef::as_ref).collect();
    let Some(at) = args.iter().position(|a| !a.starts_with('-')) else {
        return Vec::new();
    };
    let command = args[at];
    let mut out = Vec::new();
    for (i, arg) in args.iter().enumerate().skip(at + 1) {
        for r in RENAMED.iter().filter(|r| r.command == command) {
            let value = if *arg == r.old {
                args.get(i + 1).copied()
            } else if let Some(v) = arg.strip_prefix(r.old).and_then(|v| v.strip_prefix('=')) {
                Some(v)
            } else {
                continue;
            };
            if r.value.is_none_or(|old| value == Some(old)) {
                let old = match r.value {
                    Some(v) => format!("{} {v}", r.old),
                    None => r.old.to_string(),
                };
                out.push(format!(
                    "warning: `{command} {old}` is renamed `{}`; the old spelling goes in the next release",
                    r.new
                ));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::warnings;

    #[test]
    fn old_spellings_warn_and_new_ones_do_not() {
        let w = warnings(&["evaluate", "--model", "a.safetensors", "--data=x.csv"]);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("--network"), "{w:?}");
        assert_eq!(warnings(&["export", "--model=a"]).len(), 1);
        assert!(warnings(&["evaluate", "--network", "a", "--data", "x"]).is_empty());
        // `--model` is renamed per subcommand: the identified model in torque.
        assert!(warnings(&["torque", "--model", "m.json"])[0].contains("--identified"));
        // A renamed value warns only for that value.
        assert_eq!(warnings(&["identify", "--friction", "paper"]).len(), 1);
        assert!(warnings(&["identify", "--friction", "extended"]).is_empty());
        // The old flag and its old value: both named.
        assert_eq!(
            warnings(&["torque", "--friction-model", "extended"]).len(),
            1
        );
        assert!(warnings::<&str>(&[]).is_empty());
    }
}
