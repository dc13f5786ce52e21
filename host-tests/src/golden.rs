//! Parsing the QEMU binary's report and producing the host's twin of it.
use crate::compare::Record;
use anyhow::{Result, bail};
use test_kit::fixtures::GoldenModel;
use test_kit::golden::network::STEPS;
use test_kit::golden::{self, MathFn};

/// One `@suite` block of the QEMU report.
#[derive(Debug, Default)]
pub struct Suite {
    /// Suite name (`math`, `dot`, ...).
    pub name: String,
    /// Records in output order.
    pub records: Vec<Record>,
}

/// Parses the QEMU report: `@suite NAME N`, record lines `fn index input_hex output_hex`,
/// `@end NAME`, and a final `@pass`.
pub fn parse_report(text: &str) -> Result<Vec<Suite>> {
    let mut suites: Vec<Suite> = Vec::new();
    let mut current: Option<Suite> = None;
    let mut passed = false;
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            None => {}
            Some("@suite") => {
                let name = words.next().unwrap_or_default().to_string();
                current = Some(Suite {
                    name,
                    records: Vec::new(),
                });
            }
            Some("@end") => match current.take() {
                Some(s) => suites.push(s),
                None => bail!("report line {line_no}: @end without @suite"),
            },
            Some("@pass") => passed = true,
            Some(word) if word.starts_with('@') => {
                bail!("report line {line_no}: target reported `{line}`")
            }
            Some(func) => {
                let Some(suite) = current.as_mut() else {
                    bail!("report line {line_no}: record outside a suite: `{line}`");
                };
                let fields: Vec<&str> = words.collect();
                let [index, input, output] = fields[..] else {
                    bail!("report line {line_no}: expected `fn index input output`, got `{line}`");
                };
                let parse_hex = |s: &str| u32::from_str_radix(s, 16);
                match (index.parse(), parse_hex(input), parse_hex(output)) {
                    (Ok(index), Ok(input_bits), Ok(output_bits)) => suite.records.push(Record {
                        function: func.to_string(),
                        index,
                        input_bits,
                        output_bits,
                    }),
                    _ => bail!("report line {line_no}: malformed numbers in `{line}`"),
                }
            }
        }
    }
    if current.is_some() {
        bail!("report ended inside a suite (target stopped early)");
    }
    if !passed {
        bail!("report has no @pass line (target did not finish)");
    }
    Ok(suites)
}

/// The host's computation of the `math` suite, with the same firmware functions.
pub fn host_math() -> Vec<Record> {
    let mut out = Vec::with_capacity(MathFn::ALL.len() * golden::MATH_POINTS);
    for f in MathFn::ALL {
        for i in 0..golden::MATH_POINTS {
            let x = f.input(i);
            out.push(Record::new(f.name(), i, x.to_bits(), f.eval(x).to_bits()));
        }
    }
    out
}

/// The host's computation of the `dot` suite.
pub fn host_dot() -> Vec<Record> {
    (0..golden::DOT_CASES)
        .map(|case| Record::new("dot", case, case as u32, golden::dot_output(case).to_bits()))
        .collect()
}

/// The host's computation of the `cells` suite: the new cell state (`c`) and `o`
/// (`h`) of each cell, index and input = the cell; `tanh(acc + bias)` (`t`) and
/// `bias * tanh(acc)` (`m`) of each of its four lanes, index and input = 4 cells + lane.
pub fn host_cells() -> Vec<Record> {
    let (c, h, t, m) = golden::cells_output();
    let mut out = Vec::with_capacity(10 * golden::CELL_CASES);
    for j in 0..golden::CELL_CASES {
        out.push(Record::new("c", j, j as u32, c[j].to_bits()));
        out.push(Record::new("h", j, j as u32, h[j].to_bits()));
        for r in 0..4 {
            let k = 4 * j + r;
            out.push(Record::new("t", k, k as u32, t[j][r].to_bits()));
            out.push(Record::new("m", k, k as u32, m[j][r].to_bits()));
        }
    }
    out
}

/// The host's computation of the `dynamics` suite: one record per joint torque,
/// function `tau<joint>`, index and input = the case number.
pub fn host_dynamics() -> Vec<Record> {
    let model = golden::dynamics_model();
    let mut out = Vec::with_capacity(golden::DYNAMICS_CASES * golden::DYNAMICS_JOINTS);
    for case in 0..golden::DYNAMICS_CASES {
        let tau = golden::dynamics_output(&model, case);
        for (j, t) in tau.iter().enumerate() {
            out.push(Record::new(
                &format!("tau{}", j + 1),
                case,
                case as u32,
                t.to_bits(),
            ));
        }
    }
    out
}

/// The host's computation of the `features` suite (`firmware::features`: the drive's
/// friction features, linear correction and presliding states), function `f<k>`, index
/// and input = the case.
pub fn host_features() -> Vec<Record> {
    let mut out = Vec::with_capacity(golden::FEATURE_CASES * golden::FEATURE_VALUES);
    for case in 0..golden::FEATURE_CASES {
        for (k, v) in golden::feature_output(case).iter().enumerate() {
            out.push(Record::new(
                &format!("f{k}"),
                case,
                case as u32,
                v.to_bits(),
            ));
        }
    }
    out
}

/// The host's computation of the `envelope` suite (`firmware::envelope`: weight, faded
/// prediction, clamped linear stage, coverage; then the drive predictor's faded stream):
/// functions `e<k>` per case, `ey` and `ew` per step.
pub fn host_envelope() -> Vec<Record> {
    let mut out = Vec::new();
    for case in 0..golden::ENVELOPE_CASES {
        for (k, v) in golden::envelope_output(case).iter().enumerate() {
            out.push(Record::new(
                &format!("e{k}"),
                case,
                case as u32,
                v.to_bits(),
            ));
        }
    }
    golden::envelope_stream(|t, y, w| {
        out.push(Record::new("ey", t, t as u32, y.to_bits()));
        out.push(Record::new("ew", t, t as u32, w.to_bits()));
    });
    out
}

/// The host's computation of the `monitor` suite (`firmware::monitor`: the do-no-harm
/// monitor's output and gain along a walk, then its scores), function `m<k>`, index and
/// input = the case.
pub fn host_monitor() -> Vec<Record> {
    let mut out = Vec::with_capacity(golden::MONITOR_CASES * golden::MONITOR_VALUES);
    for case in 0..golden::MONITOR_CASES {
        for (k, v) in golden::monitor_output(case).iter().enumerate() {
            out.push(Record::new(
                &format!("m{k}"),
                case,
                case as u32,
                v.to_bits(),
            ));
        }
    }
    out
}

/// The host's computation of the `lstm` suite: the golden network streamed step by step.
pub fn host_lstm() -> Vec<Record> {
    let mut out = Vec::with_capacity(golden::LSTM_STEPS * golden::LSTM_O);
    golden::lstm_stream(|t, y| {
        for (k, v) in y.iter().enumerate() {
            out.push(Record::new(
                "lstm",
                t * golden::LSTM_O + k,
                t as u32,
                v.to_bits(),
            ));
        }
    });
    out
}

/// The host's computation of a quantised-kernel suite (`lstm_f32`, `lstm_int16`,
/// `lstm_int8`, `lstm_int16_layer`): the golden model streamed over `test_kit::golden::network::STEPS` steps.
pub fn host_quant(g: GoldenModel) -> Vec<Record> {
    let n = g.outputs();
    let mut out = Vec::with_capacity(STEPS * n);
    g.stream(STEPS, &mut |t, y| {
        for (k, v) in y.iter().enumerate() {
            out.push(Record::new(g.name(), t * n + k, t as u32, v.to_bits()));
        }
    });
    out
}

/// Checks a quantised-kernel suite's records against the exporter's self-check digest
/// (`SELF_CHECK_FNV` over the first `SELF_CHECK_STEPS` steps, written by
/// `model-export export`): the target computes what the exporter reported.
pub fn check_exporter_digest(g: GoldenModel, records: &[Record]) -> Result<()> {
    let (steps, want) = g.self_check();
    let n = g.outputs();
    let mut d = test_kit::golden::network::Digest::default();
    for r in records.iter().take(steps * n) {
        d.add(&[f32::from_bits(r.output_bits)]);
    }
    if records.len() < steps * n || d.0 != want {
        bail!(
            "{}: the target's first {steps} steps give digest {:#018x}, the exporter wrote {want:#018x}",
            g.name(),
            d.0
        );
    }
    Ok(())
}

/// Outcome of comparing one suite.
#[derive(Debug)]
pub struct SuiteCheck {
    /// Suite name.
    pub name: &'static str,
    /// Number of records compared, or the first mismatch.
    pub result: Result<usize, crate::compare::Mismatch>,
}

/// Compares every suite of a QEMU report with the host's computation.
pub fn check_report(report: &str) -> Result<Vec<SuiteCheck>> {
    let suites = parse_report(report)?;
    let mut host: Vec<(&'static str, Vec<Record>)> = vec![
        ("math", host_math()),
        ("dot", host_dot()),
        ("cells", host_cells()),
        ("dynamics", host_dynamics()),
        ("features", host_features()),
        ("envelope", host_envelope()),
        ("monitor", host_monitor()),
        ("lstm", host_lstm()),
    ];
    for g in GoldenModel::ALL {
        host.push((g.name(), host_quant(g)));
        let Some(suite) = suites.iter().find(|s| s.name == g.name()) else {
            bail!("the QEMU report has no `{}` suite", g.name());
        };
        check_exporter_digest(g, &suite.records)?;
    }
    let mut checks = Vec::new();
    for (name, host_records) in host {
        let Some(suite) = suites.iter().find(|s| s.name == name) else {
            bail!("the QEMU report has no `{name}` suite");
        };
        checks.push(SuiteCheck {
            name,
            result: crate::compare::compare(&suite.records, &host_records),
        });
    }
    Ok(checks)
}
