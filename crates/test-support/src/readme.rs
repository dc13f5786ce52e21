//! The commands the workspace's READMEs show, found by one rule (the tests that run them and
//! the registry check read the same list):
//!
//! - every line of a fenced code block tagged `sh`, `bash`, `shell` or `console` (in a
//!   `console` block only the lines starting with `$ `, that prefix removed); a line ending
//!   in `\` continues on the next; blank lines, `#` comment lines and trailing ` # ...`
//!   comments are dropped, and so is a line that only assigns shell variables
//!   (`ME="..."`: it sets up the lines after it);
//! - every inline code span (it may wrap across lines) that starts, after optional
//!   `NAME=value` environment assignments, with `$ME `, `cargo ` or `bash ` and has an
//!   argument. Other spans name things: `model-export export` a subcommand,
//!   `qemu-system-arm` a program, `cargo add` (one of cargo's own subcommands alone) a
//!   cargo subcommand; `cargo board-build` (an alias of the workspace) is a command.
//!
//! Whitespace runs are folded to one space. READMEs are every `README.md` under the
//! workspace root but `target/` and hidden folders, and every `.md` file under `docs/`
//! (the studies and design notes the READMEs point to).

use std::path::{Path, PathBuf};

/// One command shown in a README.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReadmeCommand {
    /// The README, relative to the workspace root (`/`-separated).
    pub readme: String,
    /// 1-based line where the command starts.
    pub line: usize,
    /// The command, whitespace folded.
    pub command: String,
}

/// Every `README.md` under `root` but `target/` and hidden folders, and every `.md` under
/// `root/docs`, sorted.
pub fn readme_files(root: &Path) -> Vec<PathBuf> {
    let docs = root.join("docs");
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            let path = e.path();
            let name = e.file_name().to_string_lossy().to_string();
            if path.is_dir() {
                if !name.starts_with('.') && name != "target" {
                    stack.push(path);
                }
            } else if name == "README.md" || (name.ends_with(".md") && path.starts_with(&docs)) {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// Every README's commands under `root`, in file then line order.
pub fn workspace_commands(root: &Path) -> std::io::Result<Vec<ReadmeCommand>> {
    let mut out = Vec::new();
    for path in readme_files(root) {
        let text = std::fs::read_to_string(&path)?;
        let rel = path
            .strip_prefix(root)
            .unwrap_or(&path)
            .components()
            .map(|c| c.as_os_str().to_string_lossy().to_string())
            .collect::<Vec<_>>()
            .join("/");
        out.extend(commands(&rel, &text));
    }
    Ok(out)
}

/// Fold whitespace runs to one space and trim.
fn fold(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Whether `s` is `NAME=value` (a shell variable assignment word).
fn is_assignment(s: &str) -> bool {
    match s.split_once('=') {
        Some((name, _)) => {
            !name.is_empty()
                && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                && !name.starts_with(|c: char| c.is_ascii_digit())
        }
        None => false,
    }
}

/// `line` without a trailing ` # comment` outside quotes.
fn strip_comment(line: &str) -> &str {
    let (mut single, mut double) = (false, false);
    let bytes = line.as_bytes();
    for (k, &b) in bytes.iter().enumerate() {
        match b {
            b'\'' if !double => single = !single,
            b'"' if !single => double = !double,
            b'#' if !single && !double && (k == 0 || bytes[k - 1].is_ascii_whitespace()) => {
                return &line[..k];
            }
            _ => {}
        }
    }
    line
}

/// Whether a shell line only assigns variables (`A=1 B="x y"`).
fn only_assigns(line: &str) -> bool {
    // Quoted values may hold spaces: drop quoted parts before splitting.
    let mut unquoted = String::new();
    let mut quote = None;
    for c in line.chars() {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, c) => unquoted.push(c),
        }
    }
    let words: Vec<&str> = unquoted.split_whitespace().collect();
    !words.is_empty() && words.iter().all(|w| is_assignment(w))
}

/// Cargo's own subcommands: `cargo add` alone in a span names the subcommand.
const CARGO_BUILT_INS: [&str; 20] = [
    "add", "bench", "build", "check", "clean", "clippy", "doc", "fetch", "fix", "fmt", "init",
    "install", "metadata", "new", "publish", "remove", "run", "test", "tree", "update",
];

/// Whether an inline span's text is a command by the rule.
fn is_inline_command(span: &str) -> bool {
    let words: Vec<&str> = span.split_whitespace().collect();
    let Some(k) = words.iter().position(|w| !is_assignment(w)) else {
        return false;
    };
    let args = &words[k + 1..];
    match words[k] {
        "$ME" | "bash" => !args.is_empty(),
        "cargo" => match args {
            [] => false,
            [sub] => !CARGO_BUILT_INS.contains(sub),
            _ => true,
        },
        _ => false,
    }
}

/// The commands of one README's text (`readme` names it in the results).
pub fn commands(readme: &str, text: &str) -> Vec<ReadmeCommand> {
    let mut out = Vec::new();
    let lines: Vec<&str> = text.lines().collect();
    // Fenced blocks; the prose between them (fences blanked) for the inline spans.
    let mut prose: Vec<&str> = Vec::with_capacity(lines.len());
    let mut fence: Option<(String, String)> = None; // (marker, info)
    let mut pending: Option<(usize, String)> = None;
    for (k, raw) in lines.iter().enumerate() {
        let trimmed = raw.trim_start();
        if let Some((marker, info)) = &fence {
            if trimmed.starts_with(marker.as_str()) && trimmed.trim_end() == marker {
                fence = None;
                pending = None;
                prose.push("");
                continue;
            }
            prose.push("");
            let shell = matches!(info.as_str(), "sh" | "bash" | "shell");
            let console = info == "console";
            if !shell && !console {
                continue;
            }
            let mut line = raw.trim();
            if pending.is_none() {
                if console {
                    match line.strip_prefix("$ ") {
                        Some(rest) => line = rest.trim(),
                        None => continue,
                    }
                }
                if line.is_empty() || line.starts_with('#') {
                    continue;
                }
            }
            let line = strip_comment(line).trim_end();
            let (body, continues) = match line.strip_suffix('\\') {
                Some(b) => (b, true),
                None => (line, false),
            };
            let (start, mut acc) = pending.take().unwrap_or((k + 1, String::new()));
            acc.push(' ');
            acc.push_str(body);
            if continues {
                pending = Some((start, acc));
            } else if !only_assigns(&acc) && !fold(&acc).is_empty() {
                out.push(ReadmeCommand {
                    readme: readme.to_string(),
                    line: start,
                    command: fold(&acc),
                });
            }
            continue;
        }
        if let Some(rest) = trimmed
            .strip_prefix("```")
            .or_else(|| trimmed.strip_prefix("~~~"))
        {
            let marker = if trimmed.starts_with("```") {
                "```"
            } else {
                "~~~"
            };
            let info = rest.split_whitespace().next().unwrap_or("").to_string();
            fence = Some((marker.to_string(), info));
            prose.push("");
            continue;
        }
        prose.push(raw);
    }
    // Inline spans over the prose (a span may wrap to the next line).
    let joined = prose.join("\n");
    let bytes = joined.as_bytes();
    let mut k = 0;
    while k < bytes.len() {
        if bytes[k] != b'`' {
            k += 1;
            continue;
        }
        let mut ticks = 0;
        while k + ticks < bytes.len() && bytes[k + ticks] == b'`' {
            ticks += 1;
        }
        let open_end = k + ticks;
        let delim = "`".repeat(ticks);
        let Some(rel) = find_closing(&joined[open_end..], &delim) else {
            k = open_end;
            continue;
        };
        let span = &joined[open_end..open_end + rel];
        if !span.contains("\n\n") && is_inline_command(span) {
            out.push(ReadmeCommand {
                readme: readme.to_string(),
                line: joined[..k].matches('\n').count() + 1,
                command: fold(span),
            });
        }
        k = open_end + rel + ticks;
    }
    out.sort_by_key(|c| c.line);
    out
}

/// Offset of the run of exactly `delim` backticks that closes a span in `s`.
fn find_closing(s: &str, delim: &str) -> Option<usize> {
    let bytes = s.as_bytes();
    let n = delim.len();
    let mut k = 0;
    while k < bytes.len() {
        if bytes[k] == b'`' {
            let mut run = 0;
            while k + run < bytes.len() && bytes[k + run] == b'`' {
                run += 1;
            }
            if run == n {
                return Some(k);
            }
            k += run;
        } else {
            k += 1;
        }
    }
    None
}

/// The first command of `readme` equal to `command`; panics when there is none (a
/// README that changed must change its test too).
pub fn readme_command(readme: &str, command: &str) -> ReadmeCommand {
    let found = readme_commands(readme, |c| c == command);
    assert!(!found.is_empty(), "{readme}: no `{command}`");
    found[0].clone()
}

/// The commands of `readme` (relative to the workspace root) that `pick` selects, in line
/// order; panics when the README cannot be read.
pub fn readme_commands(readme: &str, pick: impl Fn(&str) -> bool) -> Vec<ReadmeCommand> {
    let root = crate::workspace_root();
    let text =
        std::fs::read_to_string(root.join(readme)).unwrap_or_else(|e| panic!("{readme}: {e}"));
    commands(readme, &text)
        .into_iter()
        .filter(|c| pick(&c.command))
        .collect()
}

/// Runs `command` with `bash -c` in `dir`, with `env` added, printing it and its output;
/// returns the exit code. Panics naming the command when bash cannot start.
pub fn run_shell(command: &str, dir: &Path, env: &[(&str, String)]) -> i32 {
    println!("$ {command}");
    let out = std::process::Command::new("bash")
        .args(["-c", command])
        .current_dir(dir)
        .envs(env.iter().map(|(k, v)| (*k, v.as_str())))
        .output()
        .unwrap_or_else(|e| panic!("{command}: bash: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let tail = |s: &str| {
        s.lines()
            .rev()
            .take(30)
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect::<Vec<_>>()
            .join("\n")
    };
    println!("{}", tail(&stdout));
    if !out.status.success() {
        println!("stderr:\n{}", tail(&stderr));
    }
    out.status.code().unwrap_or(-1)
}

/// Runs `command` as [`run_shell`] does and panics, naming it and its README, unless it
/// exits 0.
pub fn run_ok(c: &ReadmeCommand, command: &str, dir: &Path, env: &[(&str, String)]) {
    let code = run_shell(command, dir, env);
    assert_eq!(
        code, 0,
        "{}:{}: `{}` (run as `{command}`) exited {code}",
        c.readme, c.line, c.command
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rule_finds_fenced_and_inline_commands_and_nothing_else() {
        let text = "# T\n\
Run `cargo xtask demo` or `model-export export`; `FIRMWARE_MODEL=$PWD/m.rs cargo\n\
board-build` builds.\n\
\n\
```sh\n\
ME=\"cargo run -p model-export --\"\n\
# a comment\n\
$ME identify --log a.csv \\\n\
    -o m.json   # trailing\n\
```\n\
\n\
```console\n\
$ cargo test -p robot\n\
output line\n\
```\n\
\n\
```text\n\
cargo not-a-command\n\
```\n\
`qemu-system-arm`, `cargo add`, `cargo qemu-run` and `bash scripts/x.sh DIR`.\n";
        let got: Vec<(usize, String)> = commands("R.md", text)
            .into_iter()
            .map(|c| (c.line, c.command))
            .collect();
        assert_eq!(
            got,
            vec![
                (2, "cargo xtask demo".to_string()),
                (2, "FIRMWARE_MODEL=$PWD/m.rs cargo board-build".to_string()),
                (8, "$ME identify --log a.csv -o m.json".to_string()),
                (13, "cargo test -p robot".to_string()),
                (20, "cargo qemu-run".to_string()),
                (20, "bash scripts/x.sh DIR".to_string()),
            ]
        );
    }
}
