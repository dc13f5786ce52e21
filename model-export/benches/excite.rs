//! Excitation design benchmark (prints a table; `cargo bench -p model-export --bench excite`).
use model_export::excite::toy::PendulumChain;
use model_export::excite::{ExcitationSettings, FourierFamily, JointLimits, design};
use std::time::Instant;

fn main() {
    for n in [3usize, 6] {
        let model = PendulumChain { joints: n };
        let lim = vec![JointLimits::symmetric(2.5, 1.2, 3.0); n];
        let settings = ExcitationSettings::default();
        let fam = FourierFamily::new(10.0, 5, &vec![0.0; n], &lim, &[], 1000.0).unwrap();
        let t = Instant::now();
        let d = design(&model, fam, &settings).unwrap();
        println!("{n} joints: {} evals, {:.2} s, cond {:.3}", d.evaluations, t.elapsed().as_secs_f64(), d.score.condition);
    }
}
