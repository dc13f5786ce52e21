//! The telemetry round trip on the host: the wrist SIL writes its run in the drive's
//! output format (`sil --candump`: a `candump -l` log of the CAN-FD frames its boards
//! send), `telemetry` reads it back into a log, `torque --dataset` turns that into a
//! compensation dataset, and `train` and `evaluate` read it. Then the log's hostile
//! variants: altered, replayed and foreign frames are dropped and counted, a wrong key
//! or a malformed line is an error naming the file (and line) that leaves the output
//! as it was.

use model_export::cli::run_args as cli;
use std::path::Path;

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

#[test]
fn sil_candump_telemetry_torque_train_evaluate() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    // An identified wrist model (as `sil_wrist.rs`).
    let (log, model) = (p("log.csv"), p("m.json"));
    cli(&[
        "simulate",
        "--seeded-trajectory",
        "1",
        "--joints",
        "4,5,6",
        "-o",
        &s(&log),
    ])
    .unwrap();
    let layout = plant_sim::SimulatedLog::reader_args(6);
    let layout: Vec<&str> = layout.iter().map(String::as_str).collect();
    let mut id = vec!["identify", "--lock", "1=0,2=0,3=0"];
    let (log_s, model_s) = (s(&log), s(&model));
    id.extend_from_slice(&["--log", &log_s, "-o", &model_s]);
    id.extend_from_slice(&layout);
    cli(&id).unwrap();

    // The SIL's run as the drives would put it on the bus.
    let key = p("robot.key");
    std::fs::write(&key, "00112233445566778899aabbccddeeff\n").unwrap();
    let bus = p("bus.log");
    cli(&[
        "sil",
        "--identified",
        &model_s,
        "--seconds",
        "3",
        "--candump",
        &s(&bus),
        "--key-file",
        &s(&key),
    ])
    .unwrap();
    let text = read(&bus);
    let lines: Vec<&str> = text.lines().collect();
    assert!(
        lines[0].starts_with("(0.000000) can0 080##1"),
        "{}",
        lines[0]
    );
    let states = lines.iter().filter(|l| l.contains(" 10")).count();
    assert!(states >= 3 * 290, "{states} state frames");

    // Back into a log.
    let tele = p("telemetry.csv");
    cli(&[
        "telemetry",
        "--log",
        &s(&bus),
        "--key-file",
        &s(&key),
        "--joints",
        "4,5,6",
        "-o",
        &s(&tele),
    ])
    .unwrap();
    let out = read(&tele);
    let header = out.lines().next().unwrap();
    assert!(
        header.starts_with("t_s,q1_rad,q2_rad,q3_rad,q4_rad,q5_rad,q6_rad,qd1_rad_s,")
            && header.ends_with(",ff4_nm,ff5_nm,ff6_nm,faults4,faults5,faults6"),
        "{header}"
    );
    let rows: Vec<Vec<f64>> = out
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    // One row per compensator tick (100 Hz over 3 s), 10 ms apart.
    assert!((295..=300).contains(&rows.len()), "{} rows", rows.len());
    assert!((rows[1][0] - rows[0][0] - 0.01).abs() < 1e-9);
    // The wrist moves, joints 1-3 are held at 0, the feedforward is the model's.
    let span = |c: usize| {
        let v: Vec<f64> = rows.iter().map(|r| r[c]).collect();
        v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
    };
    assert!(span(4) > 0.05 && span(5) > 0.05 && span(6) > 0.05);
    assert_eq!(span(1) + span(2) + span(3), 0.0);
    assert!(
        rows.iter()
            .skip(20)
            .all(|r| r[19].abs() + r[20].abs() + r[21].abs() > 0.0)
    );

    // The project's chain reads it: torque --dataset, train, evaluate.
    let data = p("data.csv");
    cli(&[
        "torque",
        "--identified",
        &model_s,
        "--log",
        &s(&tele),
        "--layout",
        "torque",
        "--header",
        "yes",
        "--log-joints",
        "6",
        "--dataset",
        "--trim-rest-rad-s",
        "0",
        "--torque-cutoff-hz",
        "0",
        "-o",
        &s(&data),
    ])
    .unwrap();
    let dataset_rows = read(&data).lines().count() - 1;
    assert_eq!(dataset_rows, rows.len());
    let net = p("net.safetensors");
    cli(&[
        "train",
        "--data",
        &s(&data),
        "--preset",
        "drive",
        "--joints",
        "4,5,6",
        "--epochs",
        "1",
        "--window",
        "20",
        "--burn-in",
        "5",
        "--embed",
        "4",
        "--hidden",
        "4",
        "--quiet",
        "--out",
        &s(&net),
        "--loss-plot",
        &s(&p("loss.svg")),
    ])
    .unwrap();
    let report = p("evaluate.json");
    cli(&[
        "evaluate",
        "--network",
        &s(&net),
        "--data",
        &s(&data),
        "--preset",
        "drive",
        "--joints",
        "4,5,6",
        "--report",
        &s(&report),
    ])
    .unwrap();
    let r: serde_json::Value = serde_json::from_str(&read(&report)).unwrap();
    assert!(r.to_string().contains("rms"), "{r}");

    // An altered frame (one hex digit of a state payload), a replayed frame and a
    // forged one: dropped and counted, the rest read as before.
    let mut hostile: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let k = hostile.iter().position(|l| l.contains(" 101##1")).unwrap() + 40;
    let k = (k..hostile.len())
        .find(|&i| hostile[i].contains(" 101##1"))
        .unwrap();
    // One hex digit of the payload, before the MAC.
    let mut c: Vec<char> = hostile[k].chars().collect();
    let i = c.len() - 20;
    c[i] = if c[i] == '0' { '1' } else { '0' };
    hostile[k] = c.into_iter().collect();
    let replayed = hostile[10].clone();
    hostile.push(replayed);
    hostile.push(format!("(9.0) can0 102##1{}", "00".repeat(48)));
    let bus2 = p("hostile.log");
    std::fs::write(&bus2, hostile.join("\n")).unwrap();
    let tele2 = p("telemetry2.csv");
    cli(&[
        "telemetry",
        "--log",
        &s(&bus2),
        "--key-file",
        &s(&key),
        "-o",
        &s(&tele2),
    ])
    .unwrap();
    let out2 = read(&tele2);
    // Every row of the hostile log's read is a row of the clean one; the altered
    // frame's tick is left out.
    let clean: std::collections::HashSet<&str> = out.lines().collect();
    assert!(out2.lines().all(|l| clean.contains(l)));
    assert_eq!(out2.lines().count(), out.lines().count() - 1);

    // A wrong key: an error naming the log; the output stays as it was.
    let wrong = p("wrong.key");
    std::fs::write(&wrong, "ffeeddccbbaa99887766554433221100").unwrap();
    let e = cli(&[
        "telemetry",
        "--log",
        &s(&bus),
        "--key-file",
        &s(&wrong),
        "-o",
        &s(&tele2),
    ])
    .unwrap_err();
    assert!(format!("{e:#}").contains("failed authentication"), "{e:#}");
    assert_eq!(read(&tele2), out2);
    // A malformed line: file, line and field.
    let mut bad = lines[..20].join("\n");
    bad.push_str("\n(1.0) can0 1Z0##1AA\n");
    let bus3 = p("bad.log");
    std::fs::write(&bus3, &bad).unwrap();
    let e = cli(&[
        "telemetry",
        "--log",
        &s(&bus3),
        "--key-file",
        &s(&key),
        "-o",
        &s(&tele2),
    ])
    .unwrap_err();
    let msg = format!("{e:#}");
    assert!(
        msg.contains("bad.log:21") && msg.contains("identifier"),
        "{msg}"
    );
    assert_eq!(read(&tele2), out2);
}
