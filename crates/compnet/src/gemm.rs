//! The one place with `unsafe` in model-export: safe, bounds-checked wrappers around two
//! SGEMM crates for row-major matrices, each tested against a plain loop.
//!
//! [`sgemm`] picks by size, as measured at the LSTM training shapes
//! (`examples/gemm_shapes.rs`, thread CPU time): the `gemm` crate (run-time dispatch up to
//! AVX-512) for the small per-step products (`[50,64]×[64,256]`: ~25-30 against ~20-23
//! GFLOP/s), `matrixmultiply` for the large time-batched ones (`[5000,64]×[64,256]` and the
//! weight gradients: ~60 against ~30 GFLOP/s). [`sgemm_gemm`] and [`sgemm_mm`] are the two
//! backends.
#![allow(unsafe_code)]

/// How an operand is read: as stored, or transposed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    /// Use the stored row-major matrix.
    N,
    /// Use its transpose.
    T,
}

/// `c[m×n] = alpha · op(a)[m×k] · op(b)[k×n] + beta · c`, all row-major and dense.
/// `a` is stored `[m][k]` for `Op::N` or `[k][m]` for `Op::T`; likewise `b`.
///
/// Panics if a slice is shorter than its shape needs (a programming error, checked
/// before any unsafe access).
#[allow(clippy::too_many_arguments)]
pub fn sgemm(
    m: usize,
    k: usize,
    n: usize,
    alpha: f32,
    a: &[f32],
    ta: Op,
    b: &[f32],
    tb: Op,
    beta: f32,
    c: &mut [f32],
) {
    if m * k * n >= 1 << 21 {
        sgemm_mm(m, k, n, alpha, a, ta, b, tb, beta, c)
    } else {
        sgemm_gemm(m, k, n, alpha, a, ta, b, tb, beta, c)
    }
}

/// Panics unless `a`, `b` and `c` hold `m×k`, `k×n` and `m×n` elements: the check both
/// backends make before any unsafe access.
fn check_lengths(m: usize, k: usize, n: usize, a: &[f32], b: &[f32], c: &[f32]) {
    assert!(
        a.len() >= m * k && b.len() >= k * n && c.len() >= m * n,
        "sgemm: operand too short"
    );
}

/// Row and column strides of `op(a)` (`m×k`) and `op(b)` (`k×n`) over row-major storage:
/// `[rsa, csa, rsb, csb]`.
fn strides(m: usize, k: usize, n: usize, ta: Op, tb: Op) -> [isize; 4] {
    let (rsa, csa) = match ta {
        Op::N => (k as isize, 1),
        Op::T => (1, m as isize),
    };
    let (rsb, csb) = match tb {
        Op::N => (n as isize, 1),
        Op::T => (1, k as isize),
    };
    [rsa, csa, rsb, csb]
}

/// [`sgemm`] on the `gemm` crate (same contract).
#[allow(clippy::too_many_arguments)]
pub fn sgemm_gemm(
    m: usize,
    k: usize,
    n: usize,
    alpha: f32,
    a: &[f32],
    ta: Op,
    b: &[f32],
    tb: Op,
    beta: f32,
    c: &mut [f32],
) {
    check_lengths(m, k, n, a, b, c);
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        c[..m * n].iter_mut().for_each(|x| *x *= beta);
        return;
    }
    let [rsa, csa, rsb, csb] = strides(m, k, n, ta, tb);
    // SAFETY: as in `sgemm_mm`: the asserted lengths cover every addressed element and
    // `c` is exclusively borrowed. `gemm` computes dst = alpha·dst + beta·lhs·rhs (its
    // alpha/beta are swapped w.r.t. BLAS); `read_dst = false` ignores dst's old contents.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            c.as_mut_ptr(),
            1,
            n as isize,
            beta != 0.0,
            a.as_ptr(),
            csa,
            rsa,
            b.as_ptr(),
            csb,
            rsb,
            beta,
            alpha,
            false,
            false,
            false,
            gemm::Parallelism::None,
        )
    }
}

/// [`sgemm`] on `matrixmultiply` (same contract).
#[allow(clippy::too_many_arguments)]
pub fn sgemm_mm(
    m: usize,
    k: usize,
    n: usize,
    alpha: f32,
    a: &[f32],
    ta: Op,
    b: &[f32],
    tb: Op,
    beta: f32,
    c: &mut [f32],
) {
    check_lengths(m, k, n, a, b, c);
    if m == 0 || n == 0 {
        return;
    }
    let [rsa, csa, rsb, csb] = strides(m, k, n, ta, tb);
    // SAFETY: the asserted lengths cover every element addressed by the strides above
    // (max index (m-1)*rs + (k-1)*cs < m*k for either layout, likewise for b and c),
    // and `c` is exclusively borrowed, so it does not alias `a` or `b`.
    unsafe {
        matrixmultiply::sgemm(
            m,
            k,
            n,
            alpha,
            a.as_ptr(),
            rsa,
            csa,
            b.as_ptr(),
            rsb,
            csb,
            beta,
            c.as_mut_ptr(),
            n as isize,
            1,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_a_plain_loop_for_every_transpose() {
        check(sgemm);
        check(sgemm_gemm);
        check(sgemm_mm);
    }

    type Gemm = fn(usize, usize, usize, f32, &[f32], Op, &[f32], Op, f32, &mut [f32]);

    fn check(f: Gemm) {
        let (m, k, n) = (5, 7, 3);
        let a: Vec<f32> = (0..m * k).map(|i| (i as f32 * 0.37).sin()).collect();
        let b: Vec<f32> = (0..k * n).map(|i| (i as f32 * 0.11).cos()).collect();
        for ta in [Op::N, Op::T] {
            for tb in [Op::N, Op::T] {
                let at = |i: usize, p: usize| {
                    if ta == Op::N {
                        a[i * k + p]
                    } else {
                        a[p * m + i]
                    }
                };
                let bt = |p: usize, j: usize| {
                    if tb == Op::N {
                        b[p * n + j]
                    } else {
                        b[j * k + p]
                    }
                };
                let mut c = vec![1.0f32; m * n];
                f(m, k, n, 2.0, &a, ta, &b, tb, 0.5, &mut c);
                for i in 0..m {
                    for j in 0..n {
                        let want: f32 =
                            2.0 * (0..k).map(|p| at(i, p) * bt(p, j)).sum::<f32>() + 0.5;
                        assert!((c[i * n + j] - want).abs() < 1e-5, "{ta:?}{tb:?} {i} {j}");
                    }
                }
            }
        }
    }
}
