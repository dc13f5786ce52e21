//! The plausibility layer every reader shares: general physical and size checks on what a
//! file or a command line says, before anything is computed or allocated from it. Each
//! check returns a message without the place; the reader adds the file, the line (or
//! message or tensor) and the field.

/// Largest number of joints any reader accepts (a robot, a log, a network's joints): far
/// above any arm, and small enough that per-joint allocations stay bounded.
pub const MAX_JOINTS: usize = 64;

/// Longest name (joint, link, column, metadata value) any reader accepts, in bytes.
pub const MAX_NAME_BYTES: usize = 256;

/// Longest simulated or streamed duration any command accepts [s] (one day).
pub const MAX_DURATION_S: f64 = 86_400.0;

/// `value` is a finite number above zero (a rate, a time constant, a smoothing width).
pub fn positive(value: f64) -> Result<(), String> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(format!("{value} must be a finite number above zero"))
    }
}

/// A lower and an upper limit, both finite, lower strictly below upper.
pub fn limits(lower: f64, upper: f64) -> Result<(), String> {
    if !(lower.is_finite() && upper.is_finite()) {
        return Err(format!("limits [{lower}, {upper}] must be finite"));
    }
    if lower >= upper {
        return Err(format!(
            "lower limit {lower} must be below upper limit {upper} (ordered and distinct)"
        ));
    }
    Ok(())
}

/// A count read from input (joints, samples, periods) within `1..=max` before anything
/// is allocated for it; `what` names the limit in the message.
pub fn count(n: usize, max: usize, what: &str) -> Result<(), String> {
    if n == 0 || n > max {
        Err(format!("{n} is not in 1..={max} ({what})"))
    } else {
        Ok(())
    }
}

/// A duration [s]: finite, above zero, at most [`MAX_DURATION_S`].
pub fn duration_s(seconds: f64) -> Result<(), String> {
    if seconds.is_finite() && seconds > 0.0 && seconds <= MAX_DURATION_S {
        Ok(())
    } else {
        Err(format!(
            "{seconds} s is not in (0, {MAX_DURATION_S}] s (MAX_DURATION_S)"
        ))
    }
}

/// A name or metadata string: at most [`MAX_NAME_BYTES`] bytes, no control characters
/// (a newline in a preset or a joint name would break every file it is written to).
pub fn name(s: &str) -> Result<(), String> {
    if s.len() > MAX_NAME_BYTES {
        return Err(format!(
            "{} bytes, longer than {MAX_NAME_BYTES} (MAX_NAME_BYTES)",
            s.len()
        ));
    }
    if let Some(c) = s.chars().find(|c| c.is_control()) {
        return Err(format!("{:?} contains the control character {c:?}", s));
    }
    Ok(())
}

/// A link's mass [kg] and rotational inertia about its centre of mass [kg·m²]: the mass
/// not negative, and the inertia that of a physical body: positive semi-definite and its
/// principal moments obeying the triangle inequality (each at most the sum of the other
/// two). Both hold exactly when `tr(I)/2 · 1 − I` (the body's second moments of mass) is
/// positive semi-definite, which is what is checked, to a tolerance of 1e-9 of the trace.
pub fn rigid_body(mass_kg: f64, inertia: &[[f64; 3]; 3]) -> Result<(), String> {
    let all = std::iter::once(mass_kg).chain(inertia.iter().flatten().copied());
    if let Some(v) = all.clone().find(|v| !v.is_finite()) {
        return Err(format!("{v} is not a finite number"));
    }
    if mass_kg < 0.0 {
        return Err(format!("negative mass {mass_kg} kg"));
    }
    for (r, c) in [(1, 0), (2, 0), (2, 1)] {
        {
            let (a, b) = (inertia[r][c], inertia[c][r]);
            if (a - b).abs() > 1e-9 * (a.abs() + b.abs()).max(f64::MIN_POSITIVE) {
                return Err(format!("inertia is not symmetric ({a} and {b})"));
            }
        }
    }
    let trace = inertia[0][0] + inertia[1][1] + inertia[2][2];
    let tol = 1e-9 * trace.abs().max(1e-300);
    if !semi_definite(inertia, tol) {
        return Err(format!(
            "inertia {inertia:?} is not positive semi-definite (no physical body has it)"
        ));
    }
    let second: [[f64; 3]; 3] = std::array::from_fn(|r| {
        std::array::from_fn(|c| -inertia[r][c] + if r == c { trace / 2.0 } else { 0.0 })
    });
    if !semi_definite(&second, tol) {
        return Err(format!(
            "inertia {inertia:?} violates the triangle inequality (a principal moment exceeds the sum of the other two: no physical body has it)"
        ));
    }
    Ok(())
}

/// Symmetric 3×3 `m` positive semi-definite within `tol`: every principal minor ≥ −tol
/// (scaled by its order).
fn semi_definite(m: &[[f64; 3]; 3], tol: f64) -> bool {
    let d = |i: usize, j: usize| m[i][i] * m[j][j] - m[i][j] * m[j][i];
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    (0..3).all(|i| m[i][i] >= -tol)
        && [(0, 1), (0, 2), (1, 2)]
            .iter()
            .all(|&(i, j)| d(i, j) >= -tol * tol.max(m[i][i].abs() + m[j][j].abs()))
        && det >= -tol * (m[0][0].abs() + m[1][1].abs() + m[2][2].abs()).powi(2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bodies_real_and_impossible() {
        let diag = |a, b, c| [[a, 0.0, 0.0], [0.0, b, 0.0], [0.0, 0.0, c]];
        assert!(rigid_body(1.0, &diag(1.0, 1.0, 1.0)).is_ok());
        assert!(rigid_body(1.0, &diag(1.0, 1.0, 2.0)).is_ok()); // a thin disc: equality
        assert!(rigid_body(0.0, &diag(0.0, 0.0, 0.0)).is_ok());
        let e = rigid_body(1.0, &diag(1.0, 1.0, 3.0)).unwrap_err();
        assert!(e.contains("triangle inequality"), "{e}");
        let e = rigid_body(1.0, &diag(1.0, -1.0, 1.0)).unwrap_err();
        assert!(e.contains("semi-definite"), "{e}");
        assert!(rigid_body(-1.0, &diag(1.0, 1.0, 1.0)).is_err());
        assert!(rigid_body(1.0, &diag(f64::NAN, 1.0, 1.0)).is_err());
    }

    #[test]
    fn limits_counts_names_durations() {
        assert!(limits(-1.0, 1.0).is_ok());
        assert!(limits(1.0, 1.0).is_err());
        assert!(limits(2.0, 1.0).is_err());
        assert!(count(1000, MAX_JOINTS, "MAX_JOINTS").is_err());
        assert!(count(0, MAX_JOINTS, "MAX_JOINTS").is_err());
        assert!(name("paper\n").is_err());
        assert!(name(&"j".repeat(200_000)).is_err());
        assert!(name("joint_4").is_ok());
        assert!(duration_s(1e308).is_err());
        assert!(duration_s(f64::NAN).is_err());
        assert!(duration_s(5.0).is_ok());
        assert!(positive(0.0).is_err());
        assert!(positive(-1.0).is_err());
    }
}
