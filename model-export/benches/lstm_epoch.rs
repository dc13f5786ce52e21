//! Seconds per training epoch of the paper's configuration (9 → 64 → LSTM 64 → 3,
//! windows of 100 steps, batch 50, Adam, RMS loss, clipping) on a 60 000-step dataset,
//! on the fused network kernel (`nn::fused_net`) with 1 and 2 threads, next to the same
//! epoch in PyTorch on the CPU with 1 and 2 threads (`scripts/bench_torch.py`, run back to
//! back when `python3 -c 'import torch'` works; otherwise its columns say so).
//!
//! `cargo bench -p model-export --bench lstm_epoch [-- --burn-in 50 --epochs 3]`
//! (`cargo test` runs it as a smoke test: 2 000 steps, H = 16, one epoch after the warm-up).
use compnet::data::Sequence;
use compnet::train::{TrainConfig, new_model, time_epochs};
use std::process::Command;
use test_support::bench::BenchRun;

fn arg(name: &str, default: usize) -> usize {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|k| args.get(k + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// PyTorch's best wall-clock and CPU s/epoch from the reference script, or `None` if it
/// cannot run.
fn torch(
    steps: usize,
    burn_in: usize,
    epochs: usize,
    hidden: usize,
    threads: usize,
) -> Option<(f64, f64)> {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/bench_torch.py");
    let out = Command::new("python3")
        .arg(script)
        .args(["--steps", &steps.to_string()])
        .args(["--burn-in", &burn_in.to_string()])
        .args(["--epochs", &epochs.to_string()])
        .args(["--hidden", &hidden.to_string()])
        .args(["--threads", &threads.to_string()])
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().find(|l| l.starts_with("| pytorch |"))?;
    let cols: Vec<&str> = line.split('|').map(str::trim).collect();
    Some((cols.get(2)?.parse().ok()?, cols.get(4)?.parse().ok()?))
}

fn main() -> anyhow::Result<()> {
    let run = BenchRun::from_args();
    let steps = arg("--steps", run.size(60_000, 2_000));
    let epochs = arg("--epochs", run.size(3, 1));
    let hidden = arg("--hidden", run.size(64, 16));
    let seq = Sequence {
        inputs: (0..steps)
            .map(|t| {
                (0..9)
                    .map(|k| (t as f32 * 0.01 * (k + 1) as f32).sin())
                    .collect()
            })
            .collect(),
        targets: (0..steps)
            .map(|t| {
                (0..3)
                    .map(|k| (t as f32 * 0.013 * (k + 1) as f32).cos())
                    .collect()
            })
            .collect(),
        ..Default::default()
    };
    let pair = |s: (f64, f64)| format!("{:.3} ({:.3})", s.0, s.1);
    let fmt = |s: Option<(f64, f64)>| s.map_or("n/a".to_string(), pair);
    let ratio = |a: (f64, f64), b: Option<(f64, f64)>| {
        b.map_or("n/a".to_string(), |b| {
            format!("{:.2} ({:.2})", a.0 / b.0, a.1 / b.1)
        })
    };
    println!(
        "fused network kernel (nn::fused_net) vs PyTorch CPU, {steps} steps, H = {hidden}, batch 50, \
         window 100; s/epoch = wall clock (process CPU seconds), best of {epochs} epochs after \
         one warm-up; ratio = ours / torch"
    );
    println!(
        "| burn-in | batches | ours 1 thr | ours 2 thr | torch 1 thr | torch 2 thr | ours 1 / torch 1 | ours 2 / torch 2 |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|");
    for burn_in in [0, arg("--burn-in", 50)] {
        let mut ours = Vec::new();
        let mut batches = 0;
        for threads in [1, 2] {
            let cfg = TrainConfig {
                embed: hidden,
                hidden,
                burn_in,
                progress: false,
                threads,
                ..Default::default()
            };
            let m = new_model(
                &seq,
                (0..9).map(|k| format!("x{k}")).collect(),
                (0..3).map(|k| format!("y{k}")).collect(),
                "custom",
                &cfg,
            )?;
            let (windows, times) = time_epochs(&m, &[&seq], &cfg, 0.003, epochs + 1)?;
            let best =
                |f: fn(&(f64, f64)) -> f64| times[1..].iter().map(f).fold(f64::INFINITY, f64::min);
            ours.push((best(|t| t.0), best(|t| t.1)));
            batches = windows.div_ceil(cfg.batch);
        }
        let t1 = torch(steps, burn_in, epochs, hidden, 1);
        let t2 = torch(steps, burn_in, epochs, hidden, 2);
        println!(
            "| {burn_in} | {batches} | {} | {} | {} | {} | {} | {} |",
            pair(ours[0]),
            pair(ours[1]),
            fmt(t1),
            fmt(t2),
            ratio(ours[0], t1),
            ratio(ours[1], t2)
        );
    }
    Ok(())
}
