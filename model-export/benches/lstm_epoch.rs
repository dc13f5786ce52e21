//! Seconds per training epoch of the paper's configuration (9 → 64 → LSTM 64 → 3,
//! windows of 100 steps, batch 50, Adam, RMS loss, clipping) on a 60 000-step dataset,
//! with the fused LSTM op. Compare with `python3 scripts/bench_torch.py` (same work).
//!
//! `cargo bench -p model-export --bench lstm_epoch [-- --burn-in 50 --epochs 3]`
use model_export::nn::data::Sequence;
use model_export::nn::train::{TrainConfig, new_model, time_epochs};

fn arg(name: &str, default: usize) -> usize {
    let args: Vec<String> = std::env::args().collect();
    args.iter().position(|a| a == name).and_then(|k| args.get(k + 1)).and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn main() -> anyhow::Result<()> {
    let steps = arg("--steps", 60_000);
    let epochs = arg("--epochs", 3);
    let hidden = arg("--hidden", 64);
    let mut rows = Vec::new();
    for burn_in in [0, arg("--burn-in", 50)] {
        let cfg = TrainConfig { embed: hidden, hidden, burn_in, progress: false, ..Default::default() };
        let seq = Sequence {
            inputs: (0..steps).map(|t| (0..9).map(|k| (t as f32 * 0.01 * (k + 1) as f32).sin()).collect()).collect(),
            targets: (0..steps).map(|t| (0..3).map(|k| (t as f32 * 0.013 * (k + 1) as f32).cos()).collect()).collect(),
            ..Default::default()
        };
        let m = new_model(&seq, (0..9).map(|k| format!("x{k}")).collect(), (0..3).map(|k| format!("y{k}")).collect(), "custom", &cfg)?;
        let (windows, times) = time_epochs(&m, &[&seq], &cfg, 0.003, epochs + 1)?;
        let best = times[1..].iter().cloned().fold(f64::INFINITY, f64::min);
        let batches = windows.div_ceil(cfg.batch);
        rows.push((burn_in, windows, batches, best));
    }
    println!("candle + fused LSTM op (1 thread, matrixmultiply), {steps} steps, H = {hidden}, batch 50, window 100");
    println!("| burn-in | windows | batches | s/epoch (best of {epochs}) | ms/batch |");
    println!("|---:|---:|---:|---:|---:|");
    for (b, w, n, s) in rows {
        println!("| {b} | {w} | {n} | {s:.3} | {:.1} |", 1000.0 * s / n as f64);
    }
    Ok(())
}
