//! Bit-for-bit comparison of target and host results.
use std::fmt;

/// One computed value: which function, which case, input and output as f32 bits.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Record {
    /// Function name.
    pub function: String,
    /// Case index within the function.
    pub index: usize,
    /// Input (f32 bits; for vector cases, the case number).
    pub input_bits: u32,
    /// Output (f32 bits).
    pub output_bits: u32,
}

impl Record {
    /// A record from its parts.
    pub fn new(function: &str, index: usize, input_bits: u32, output_bits: u32) -> Self {
        Record {
            function: function.to_string(),
            index,
            input_bits,
            output_bits,
        }
    }
}

/// The first difference between target and host.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Mismatch {
    /// Different number of records.
    Count {
        /// Records from the target.
        target: usize,
        /// Records from the host.
        host: usize,
    },
    /// The records at `position` are for different cases or inputs.
    Case {
        /// Position in the record list.
        position: usize,
        /// Target's record.
        target: Record,
        /// Host's record.
        host: Record,
    },
    /// Same case and input, different output bits.
    Output {
        /// Host's record (function, index, input).
        host: Record,
        /// Target's output bits.
        target_bits: u32,
    },
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Mismatch::Count { target, host } => {
                write!(f, "target produced {target} records, host {host}")
            }
            Mismatch::Case {
                position,
                target,
                host,
            } => write!(
                f,
                "record {position}: target has {} #{} input {:#010x}, host has {} #{} input {:#010x}",
                target.function,
                target.index,
                target.input_bits,
                host.function,
                host.index,
                host.input_bits
            ),
            Mismatch::Output { host, target_bits } => write!(
                f,
                "{} #{}: input {:#010x} ({:e}): target {:#010x} ({:e}) != host {:#010x} ({:e})",
                host.function,
                host.index,
                host.input_bits,
                f32::from_bits(host.input_bits),
                target_bits,
                f32::from_bits(*target_bits),
                host.output_bits,
                f32::from_bits(host.output_bits)
            ),
        }
    }
}

impl std::error::Error for Mismatch {}

/// Compares record lists in order; returns the count compared or the first mismatch.
pub fn compare(target: &[Record], host: &[Record]) -> Result<usize, Mismatch> {
    for (position, (t, h)) in target.iter().zip(host).enumerate() {
        if t.function != h.function || t.index != h.index || t.input_bits != h.input_bits {
            return Err(Mismatch::Case {
                position,
                target: t.clone(),
                host: h.clone(),
            });
        }
        if t.output_bits != h.output_bits {
            return Err(Mismatch::Output {
                host: h.clone(),
                target_bits: t.output_bits,
            });
        }
    }
    if target.len() != host.len() {
        return Err(Mismatch::Count {
            target: target.len(),
            host: host.len(),
        });
    }
    Ok(host.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn records() -> Vec<Record> {
        (0..5)
            .map(|i| Record::new("exp", i, (i as f32).to_bits(), (i as f32).exp().to_bits()))
            .collect()
    }

    #[test]
    fn identical_lists_pass() {
        assert_eq!(compare(&records(), &records()), Ok(5));
    }

    #[test]
    fn a_one_ulp_difference_is_named() {
        let host = records();
        let mut target = records();
        target[3].output_bits += 1;
        let err = compare(&target, &host).unwrap_err();
        assert_eq!(
            err,
            Mismatch::Output {
                host: host[3].clone(),
                target_bits: host[3].output_bits + 1
            }
        );
        let text = err.to_string();
        assert!(text.starts_with("exp #3: input 0x40400000"), "{text}");
        assert!(
            text.contains(&format!("{:#010x}", host[3].output_bits + 1)),
            "{text}"
        );
    }

    #[test]
    fn wrong_input_and_length_are_named() {
        let host = records();
        let mut target = records();
        target[1].input_bits ^= 1;
        assert!(matches!(
            compare(&target, &host),
            Err(Mismatch::Case { position: 1, .. })
        ));
        assert_eq!(
            compare(&host[..4], &host),
            Err(Mismatch::Count { target: 4, host: 5 })
        );
    }
}
