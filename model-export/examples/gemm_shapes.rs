//! SGEMM backends at the LSTM training shapes (B = 50, T = 100, E = H = 64): microseconds
//! per call of `nn::gemm::sgemm_gemm` (`gemm` crate) and `nn::gemm::sgemm_mm` (`matrixmultiply`),
//! in thread CPU time (`/proc/thread-self/schedstat`, so a loaded machine does not skew
//! the comparison; wall clock where that file is missing).
//!
//! `cargo run --release -p model-export --example gemm_shapes`
use compnet::gemm::{Op, sgemm_gemm, sgemm_mm};
use std::time::Instant;

/// Nanoseconds this thread has run on a CPU, or wall-clock nanoseconds if unknown.
fn cpu_ns(wall: Instant) -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .unwrap_or_else(|| wall.elapsed().as_nanos() as f64)
}

type Gemm = fn(usize, usize, usize, f32, &[f32], Op, &[f32], Op, f32, &mut [f32]);

fn time(f: Gemm, m: usize, k: usize, n: usize, ta: Op, tb: Op, beta: f32) -> f64 {
    let a: Vec<f32> = (0..m * k).map(|i| (i as f32 * 0.37).sin()).collect();
    let b: Vec<f32> = (0..k * n).map(|i| (i as f32 * 0.11).cos()).collect();
    let mut c = vec![0.0f32; m * n];
    let reps = (2e8 / (m * k * n) as f64).clamp(3.0, 20000.0) as usize;
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let wall = Instant::now();
        let t0 = cpu_ns(wall);
        for _ in 0..reps {
            f(m, k, n, 1.0, &a, ta, &b, tb, beta, &mut c);
        }
        best = best.min((cpu_ns(wall) - t0) * 1e-9 / reps as f64);
    }
    std::hint::black_box(&c);
    1e6 * best
}

fn main() {
    let (b, t, e, h) = (50, 100, 64, 64);
    let shapes = [
        (
            "recurrent h·W_hhᵀ (per step)",
            b,
            h,
            4 * h,
            Op::N,
            Op::T,
            1.0,
        ),
        ("BPTT dA·W_hh (per step)", b, 4 * h, h, Op::N, Op::N, 1.0),
        (
            "input projection emb·W_ihᵀ",
            t * b,
            e,
            4 * h,
            Op::N,
            Op::T,
            0.0,
        ),
        ("dW_ih = dAᵀ·emb", 4 * h, t * b, e, Op::T, Op::N, 0.0),
        ("d emb = dA·W_ih", t * b, 4 * h, e, Op::N, Op::N, 0.0),
    ];
    println!("| shape (m×k×n) | what | gemm µs | GFLOP/s | matrixmultiply µs | GFLOP/s |");
    println!("|---|---|---:|---:|---:|---:|");
    for (what, m, k, n, ta, tb, beta) in shapes {
        let flop = 2.0 * (m * k * n) as f64;
        let g = time(sgemm_gemm, m, k, n, ta, tb, beta);
        let mm = time(sgemm_mm, m, k, n, ta, tb, beta);
        println!(
            "| {m}×{k}×{n} | {what} | {g:.1} | {:.0} | {mm:.1} | {:.0} |",
            flop / g / 1e3,
            flop / mm / 1e3
        );
    }
}
