//! The one joint grammar of the command line: joints are 1-based robot joint numbers;
//! `--joints 4,5,6` selects them and `--lock J=RAD,...` holds joints at an angle.
use anyhow::{Context, Result, bail};

/// The `--lock J=RAD` entries parsed: (0-based joint index, position in rad), in order.
pub fn lock_indices(specs: &[String]) -> Result<Vec<(usize, f64)>> {
    let mut locked = Vec::with_capacity(specs.len());
    for spec in specs {
        let (a, b) = spec
            .split_once('=')
            .with_context(|| format!("--lock '{spec}': expected J=RAD (1-based joint, rad)"))?;
        let number: usize = a
            .trim()
            .parse()
            .with_context(|| format!("--lock '{spec}': joint"))?;
        let q_rad: f64 = b
            .trim()
            .parse()
            .with_context(|| format!("--lock '{spec}': position"))?;
        if number == 0 || !q_rad.is_finite() {
            bail!("--lock '{spec}': joint must be 1 or more and the position finite");
        }
        locked.push((number - 1, q_rad));
    }
    Ok(locked)
}

#[cfg(test)]
mod tests {
    use super::lock_indices;

    #[test]
    fn lock_is_one_based_and_rejects_bad_entries() {
        let ok = lock_indices(&["1=0".into(), " 3 = -1.5".into()]).unwrap();
        assert_eq!(ok, vec![(0, 0.0), (2, -1.5)]);
        for bad in ["0=1", "2", "x=1", "2=nan", "2=inf"] {
            assert!(lock_indices(&[bad.into()]).is_err(), "{bad}");
        }
    }
}
