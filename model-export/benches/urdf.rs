//! Benchmark: URDF reading time against size (a chain of N revolute joints, and a binary
//! tree of fixed joints on one moving joint). Reading is linear: the time per joint stays
//! flat as N grows. Prints a table (wall-clock, best of 3); run with
//! `cargo bench -p model-export --bench urdf` (`cargo test` runs it as a smoke test on
//! small sizes).
use robot::Robot;
use std::time::Instant;
use test_support::bench::BenchRun;

// The reading tests' long chain (one source).
#[path = "../../crates/robot/tests/support/urdf_chain.rs"]
mod urdf_chain;

fn fixed_tree(n: usize) -> String {
    let link = |name: &str| {
        format!(
            "  <link name=\"{name}\"><inertial><mass value=\"1\"/><inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/></inertial></link>\n"
        )
    };
    let mut s = String::from("<robot name=\"tree\">\n");
    s.push_str(&link("base"));
    s.push_str(&link("t1"));
    s.push_str("  <joint name=\"j\" type=\"revolute\"><parent link=\"base\"/><child link=\"t1\"/><axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"10\" velocity=\"2\"/></joint>\n");
    for i in 2..=n {
        s.push_str(&link(&format!("t{i}")));
        s.push_str(&format!(
            "  <joint name=\"f{i}\" type=\"fixed\"><parent link=\"t{}\"/><child link=\"t{i}\"/><origin xyz=\"0 0.01 0\"/></joint>\n",
            i / 2
        ));
    }
    s.push_str("</robot>\n");
    s
}

fn best_of_3(text: &str) -> f64 {
    (0..3)
        .map(|_| {
            let t = Instant::now();
            let r = Robot::from_urdf_str(text, "bench.urdf").expect("parses");
            std::hint::black_box(r);
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let run = BenchRun::from_args();
    println!("| shape | joints | bytes | read [ms] | per joint [us] |");
    println!("|---|---:|---:|---:|---:|");
    // A modelled chain has at most `artifacts::plausible::MAX_JOINTS` (64) joints.
    for n in run.size(vec![16, 32, 64], vec![16, 64]) {
        let t = urdf_chain::chain_urdf(n);
        let s = best_of_3(&t);
        println!(
            "| revolute chain | {n} | {} | {:.1} | {:.2} |",
            t.len(),
            s * 1e3,
            s * 1e6 / n as f64
        );
    }
    for n in run.size(vec![1023, 4095], vec![63]) {
        let t = fixed_tree(n);
        let s = best_of_3(&t);
        println!(
            "| binary tree of fixed joints | {n} | {} | {:.1} | {:.2} |",
            t.len(),
            s * 1e3,
            s * 1e6 / n as f64
        );
    }
}
