//! The environment policy: an absence is one skip line locally; under `CI=true` it fails
//! the test when CI provides the missing thing, and stays a skip when it does not. Each
//! case runs this test binary again (one test, `--exact`) with `CI` set or cleared.
use std::process::Command;

/// Runs the hidden `child` test in a new process with `CI` as given and `ci_provides`.
fn run_child(ci: Option<&str>, ci_provides: bool) -> (bool, String) {
    let mut cmd = Command::new(std::env::current_exe().unwrap());
    cmd.args(["--exact", "child", "--nocapture", "--test-threads", "1"])
        .env(
            "SKIP_POLICY_CHILD",
            if ci_provides { "ci" } else { "local" },
        );
    match ci {
        Some(v) => cmd.env("CI", v),
        None => cmd.env_remove("CI"),
    };
    let out = cmd.output().unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    (out.status.success(), text)
}

/// The skip a parent test asks for (does nothing when run on its own).
#[test]
fn child() {
    match std::env::var("SKIP_POLICY_CHILD").as_deref() {
        Ok("ci") => test_support::skip("a target test", "qemu-system-arm", true),
        Ok("local") => test_support::skip("a torch test", "python3 with torch", false),
        _ => {}
    }
}

#[test]
fn an_absence_is_one_skip_line_locally_and_a_failure_in_ci_for_what_ci_provides() {
    let (ok, text) = run_child(None, true);
    assert!(ok, "{text}");
    // One line (libtest may print the test's name before it on the same line).
    let skips: Vec<&str> = text.lines().filter(|l| l.contains("skipped: ")).collect();
    assert_eq!(skips.len(), 1, "{text}");
    assert!(
        skips[0].ends_with("skipped: a target test: needs qemu-system-arm"),
        "{text}"
    );

    let (ok, text) = run_child(Some("true"), true);
    assert!(!ok, "{text}");
    assert!(text.contains("which CI provides"), "{text}");

    let (ok, text) = run_child(Some("true"), false);
    assert!(ok, "{text}");
    assert!(
        text.contains("skipped: a torch test: needs python3 with torch"),
        "{text}"
    );
}
