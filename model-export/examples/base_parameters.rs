//! Prints a robot's base parameters: count, rank decision gap, and expressions.
//!
//! `cargo run -p model-export --example base_parameters -- ROBOT.(urdf|toml) [--rigid] [--paper]`
use robot::base::{BaseParameters, RANK_TOLERANCE};
use robot::{ModelTerms, Robot};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.iter().find(|a| !a.starts_with("--")) else {
        anyhow::bail!("usage: base_parameters ROBOT.(urdf|toml) [--rigid] [--paper]");
    };
    let mut robot = Robot::load(path)?;
    if args.iter().any(|a| a == "--rigid") {
        robot.terms = ModelTerms::rigid_body_only();
    }
    if args.iter().any(|a| a == "--paper") {
        robot = robot.default_paper_selection();
    }
    let base = BaseParameters::compute(&robot, 1)?;
    println!(
        "{}: {} modelled joints, {} standard -> {} base parameters (seed {}, {} states)",
        robot.name,
        robot.n_modelled(),
        robot.parameter_count(),
        base.count(),
        base.seed,
        base.samples
    );
    println!(
        "rank tolerance {RANK_TOLERANCE:e}: smallest kept residual {:.3e}, largest dropped {:.3e}; relation residual {:.3e}",
        base.smallest_kept_residual, base.largest_dropped_residual, base.relation_residual
    );
    for e in base.expressions() {
        println!("  {e}");
    }
    Ok(())
}
