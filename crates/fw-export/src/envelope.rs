//! The generated file's `ENVELOPE`: each output joint's training envelope
//! (`firmware::envelope::JointEnvelope`) as a const array, or the unbounded envelope for
//! a model that carries none by an explicit choice (a seeded test network, `export
//! --no-envelope`). Numbers only: no input text reaches the file.
use compnet::LstmModel;
use firmware::envelope::{JointEnvelope, Range};
use std::fmt::Write as _;

fn f32_lit(x: f32) -> String {
    let s = format!("{x:?}");
    if s.contains('.') || s.contains('e') {
        s
    } else {
        format!("{s}.0")
    }
}

fn range(r: &Range) -> String {
    format!(
        "firmware::envelope::Range::new({}, {})",
        f32_lit(r.lo),
        f32_lit(r.hi)
    )
}

fn ranges(v: &[Range]) -> String {
    let items: Vec<String> = v.iter().map(range).collect();
    format!(
        "[\n            {},\n        ]",
        items.join(",\n            ")
    )
}

fn joint(e: &JointEnvelope) -> String {
    if *e == JointEnvelope::UNBOUNDED {
        return "firmware::envelope::JointEnvelope::UNBOUNDED".to_string();
    }
    format!(
        "firmware::envelope::JointEnvelope {{\n        q_rad: {},\n        drive: {},\n        friction: {},\n        coverage: {:#018x},\n    }}",
        range(&e.q_rad),
        ranges(&e.drive),
        ranges(&e.friction),
        e.coverage
    )
}

/// Appends `ENVELOPE` for `m`'s outputs: its recorded envelopes, or unbounded ones when
/// it has none.
pub fn write_envelope(s: &mut String, m: &LstmModel) {
    let _ = writeln!(
        s,
        "/// Training envelope of each output's joint (`firmware::envelope`): ranges of the\n\
         /// angle, the drive inputs and the friction features, and the (q, qd) coverage\n\
         /// cells; `UNBOUNDED` where the model carries none."
    );
    let items: Vec<String> = if m.envelope.is_empty() {
        vec![joint(&JointEnvelope::UNBOUNDED); m.dims.output]
    } else {
        m.envelope.iter().map(joint).collect()
    };
    let _ = writeln!(
        s,
        "pub const ENVELOPE: [firmware::envelope::JointEnvelope; OUTPUTS] = [\n    {},\n];",
        items.join(",\n    ")
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::nn::reference::LstmDims;

    #[test]
    fn renders_recorded_or_unbounded_envelopes() {
        let dims = LstmDims {
            input: 3,
            embed: 2,
            hidden: 2,
            output: 2,
        };
        let mut m = LstmModel::init(dims, 1);
        let mut s = String::new();
        write_envelope(&mut s, &m);
        assert_eq!(s.matches("JointEnvelope::UNBOUNDED").count(), 2, "{s}");
        let mut e = JointEnvelope::UNBOUNDED;
        e.q_rad = Range::new(-1.0, 2.5e-8);
        e.drive = [Range::new(0.0, 1.0); firmware::features::DRIVE_INPUTS_PER_JOINT];
        e.friction = [Range::new(-3.0, 3.0); firmware::features::FRICTION_FEATURES];
        e.coverage = 5;
        m.envelope = vec![e, JointEnvelope::UNBOUNDED];
        let mut s = String::new();
        write_envelope(&mut s, &m);
        assert!(s.contains("Range::new(-1.0, 2.5e-8)"), "{s}");
        assert!(s.contains("coverage: 0x0000000000000005"), "{s}");
        assert_eq!(s.matches("JointEnvelope::UNBOUNDED").count(), 1);
    }
}
