//! One vocabulary on the command line: every flag of every subcommand, listed by clap
//! introspection, against the glossary in the top README.
use clap::CommandFactory;
use model_export::args::renamed::RENAMED;
use model_export::cli::Cli;
use std::collections::BTreeSet;

/// Words that name a glossary concept (or an old spelling of one): a flag made with any
/// of them must be one of the glossary's flags.
const CONCEPT_WORDS: &[&str] = &[
    "robot",
    "log",
    "logs",
    "data",
    "validate",
    "validation",
    "model",
    "identified",
    "network",
    "lstm",
    "torch",
    "net",
    "out",
    "output",
    "dir",
    "json",
    "markdown",
    "md",
    "report",
    "joint",
    "joints",
    "lock",
    "locked",
    "preset",
    "paper",
    "drive",
    "gains",
    "constants",
];

/// The flags the README's glossary names (`--flag` in its table).
fn glossary_flags() -> BTreeSet<String> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../README.md");
    let text = std::fs::read_to_string(&path).expect("README.md");
    let start = text
        .find("\n## Glossary\n")
        .expect("README has a `## Glossary`");
    let section = &text[start + 1..];
    let end = section[3..].find("\n## ").map_or(section.len(), |e| e + 3);
    let mut flags = BTreeSet::new();
    for (i, _) in section[..end].match_indices("`--") {
        let rest = &section[..end][i + 1..];
        let flag: String = rest
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
            .collect();
        flags.insert(flag);
    }
    flags
}

/// Every subcommand's name and its long flags: (visible, hidden or alias).
fn every_flag() -> Vec<(String, Vec<String>, Vec<String>)> {
    let cli = Cli::command();
    cli.get_subcommands()
        .map(|sub| {
            let mut visible = Vec::new();
            let mut hidden = Vec::new();
            for arg in sub.get_arguments() {
                let Some(long) = arg.get_long() else { continue };
                if long == "help" || long == "version" {
                    continue;
                }
                if arg.is_hide_set() {
                    hidden.push(format!("--{long}"));
                } else {
                    visible.push(format!("--{long}"));
                }
                for alias in arg.get_all_aliases().unwrap_or_default() {
                    hidden.push(format!("--{alias}"));
                }
            }
            (sub.get_name().to_string(), visible, hidden)
        })
        .collect()
}

#[test]
fn every_flag_is_in_the_glossary_or_names_no_glossary_concept() {
    let glossary = glossary_flags();
    assert!(glossary.contains("--network") && glossary.contains("--identified"));
    let mut used = BTreeSet::new();
    let mut outside = Vec::new();
    let mut count = 0;
    for (command, visible, _) in every_flag() {
        for flag in visible {
            count += 1;
            let concept = flag[2..].split('-').any(|w| CONCEPT_WORDS.contains(&w));
            if glossary.contains(&flag) {
                used.insert(flag);
            } else if concept {
                outside.push(format!("{command} {flag}"));
            }
        }
    }
    println!(
        "{count} visible flags over every subcommand; {} glossary flags used",
        used.len()
    );
    assert!(
        outside.is_empty(),
        "flags naming a glossary concept outside the glossary: {outside:?}"
    );
    let unused: Vec<_> = glossary.difference(&used).collect();
    assert!(
        unused.is_empty(),
        "glossary flags no subcommand has: {unused:?}"
    );
}

#[test]
fn every_old_spelling_is_hidden_warns_and_still_parses() {
    let mut count = 0;
    for (command, visible, hidden) in every_flag() {
        for old in &hidden {
            count += 1;
            assert!(
                RENAMED
                    .iter()
                    .any(|r| r.command == command && r.old == *old && r.value.is_none()),
                "`{command} {old}` is hidden but warns nothing (add it to RENAMED)"
            );
        }
        for r in RENAMED.iter().filter(|r| r.command == command) {
            assert!(
                hidden.contains(&r.old.to_string())
                    || (r.value.is_some() && visible.contains(&r.old.to_string())),
                "RENAMED `{command} {}` is no flag of the command",
                r.old
            );
        }
    }
    println!("{count} hidden old spellings, each warning");
    assert!(RENAMED.iter().all(|r| {
        Cli::command()
            .get_subcommands()
            .any(|s| s.get_name() == r.command)
    }));
}

#[test]
fn the_preset_values_are_the_firmware_presets() {
    let want: Vec<&str> = firmware::nn::format::FeaturePreset::ALL
        .iter()
        .map(|p| p.name())
        .collect();
    let cli = Cli::command();
    let mut seen = 0;
    for sub in cli.get_subcommands() {
        for arg in sub
            .get_arguments()
            .filter(|a| a.get_long() == Some("preset"))
        {
            let values: Vec<String> = arg
                .get_possible_values()
                .iter()
                .map(|v| v.get_name().to_string())
                .collect();
            assert_eq!(values, want, "{} --preset", sub.get_name());
            seen += 1;
        }
    }
    assert!(seen >= 3, "train, evaluate and export take --preset");
}

#[test]
fn an_old_spelling_parses_as_the_new_one() {
    let old = model_export::cli::parse_from([
        "model-export",
        "evaluate",
        "--model",
        "n.safetensors",
        "--data",
        "d.csv",
        "--paper-output",
        "next",
    ])
    .expect("old spelling parses");
    let new = model_export::cli::parse_from([
        "model-export",
        "evaluate",
        "--network",
        "n.safetensors",
        "--data",
        "d.csv",
        "--preset",
        "paper",
    ])
    .expect("new spelling parses");
    let (model_export::cli::Command::Evaluate(a), model_export::cli::Command::Evaluate(b)) =
        (old.command, new.command)
    else {
        panic!("evaluate");
    };
    assert_eq!(a.network, b.network);
    assert_eq!(
        a.features.spec().unwrap().preset,
        b.features.spec().unwrap().preset
    );
    // No hidden default form: `--preset paper` is the paper's next-step form.
    assert_eq!(b.features.spec().unwrap().preset, "paper");
}
