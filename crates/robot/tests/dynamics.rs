//! Proof for the dynamics core: regressor vs an independent spatial-vector
//! (Featherstone) Newton-Euler, power balance, base parameter counts and grouping,
//! f32 firmware model vs f64, and bad-input errors.
use nalgebra::{DVector, Matrix3, Matrix6, Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robot::base::BaseParameters;
use robot::dynamics::{
    bias_forces, firmware_model::build_firmware_model, forward_kinematics, full_joint_positions,
    mass_matrix, regressor, rnea, stack_regressors,
};
use robot::{JointMode, ModelTerms, Robot, axis_rotation};

/// A UR5e-like 6R arm in standard DH (test robot; masses and inertias invented).
const UR_LIKE_STANDARD: &str = r#"
name = "ur-like"
convention = "standard"
gravity = [0.0, 0.0, -9.81]
[terms]
viscous_friction = true
coulomb_friction = true
friction_offset = true
coulomb_smoothing = 0.02
rotor_inertia = true
[[joint]]
name = "j1"
a = 0.0
alpha = 1.5707963267948966
d = 0.1625
mass = 3.7
com = [0.0, -0.02561, 0.00193]
inertia = [0.0084, 0.0064, 0.0084, 0.0001, 0.0, 0.0002]
rotor_inertia = 0.3
friction_viscous = 3.0
friction_coulomb = 5.0
friction_offset = 0.2
[[joint]]
name = "j2"
a = -0.425
alpha = 0.0
d = 0.0
mass = 8.393
com = [0.2125, 0.0, 0.11336]
inertia = [0.0151, 0.1338, 0.1331, 0.0, 0.001, 0.0]
rotor_inertia = 0.3
[[joint]]
name = "j3"
a = -0.3922
alpha = 0.0
d = 0.0
theta_offset = 0.1
mass = 2.33
com = [0.15, 0.0, 0.0265]
inertia = [0.0040, 0.0311, 0.0306, 0.0, 0.0004, 0.0]
rotor_inertia = 0.1
[[joint]]
name = "j4"
a = 0.0
alpha = 1.5707963267948966
d = 0.1333
mass = 1.219
com = [0.0, -0.0018, 0.01634]
inertia = [0.0022, 0.0021, 0.0016, 0.0, 0.0, 0.0001]
rotor_inertia = 0.05
friction_viscous = 1.0
friction_coulomb = 2.0
[[joint]]
name = "j5"
a = 0.0
alpha = -1.5707963267948966
d = 0.0997
mass = 1.219
com = [0.0, 0.0018, 0.01634]
inertia = [0.0022, 0.0021, 0.0016, 0.0, 0.0, 0.0]
rotor_inertia = 0.05
friction_viscous = 1.0
friction_coulomb = 2.0
[[joint]]
name = "j6"
a = 0.0
alpha = 0.0
d = 0.0996
mass = 0.1879
com = [0.0, 0.0, -0.001159]
inertia = [0.0001, 0.0001, 0.0001, 0.0, 0.0, 0.0]
rotor_inertia = 0.02
friction_viscous = 0.8
friction_coulomb = 1.5
"#;

fn ur_like() -> Robot {
    Robot::from_dh_toml_str(UR_LIKE_STANDARD, "ur_like.toml").expect("test robot parses")
}

fn ur10e() -> Option<Robot> {
    let path = test_support::ur10e_dir("the UR10e dynamics checks")?.join("ur10e.urdf");
    Some(Robot::load(&path).expect("ur10e.urdf loads"))
}

fn planar_2r() -> Robot {
    Robot::load(test_support::robots_dir().join("planar_2r.toml")).expect("example robot loads")
}

fn random_state(rng: &mut ChaCha8Rng, n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let q = (0..n).map(|_| rng.gen_range(-3.0..3.0)).collect();
    let qd = (0..n).map(|_| rng.gen_range(-2.0..2.0)).collect();
    let qdd = (0..n).map(|_| rng.gen_range(-6.0..6.0)).collect();
    (q, qd, qdd)
}

fn random_theta(rng: &mut ChaCha8Rng, p: usize) -> DVector<f64> {
    DVector::from_iterator(p, (0..p).map(|_| rng.gen_range(-2.0..2.0)))
}

// ---------------------------------------------------------------------------------
// Independent inverse dynamics: Featherstone's spatial-vector RNEA (angular first).

fn sk(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Motion transform from frame A to frame B, where B has orientation `e` (B axes in A:
/// `rot`, so `e = rot^T`) and origin `r` in A.
fn xform(rot: &Matrix3<f64>, r: &Vector3<f64>) -> Matrix6<f64> {
    let e = rot.transpose();
    let mut x = Matrix6::zeros();
    x.fixed_view_mut::<3, 3>(0, 0).copy_from(&e);
    x.fixed_view_mut::<3, 3>(3, 3).copy_from(&e);
    x.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-e * sk(r)));
    x
}

fn crm(v: &Vector6<f64>) -> Matrix6<f64> {
    let w = Vector3::new(v[0], v[1], v[2]);
    let u = Vector3::new(v[3], v[4], v[5]);
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&sk(&w));
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&sk(&w));
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(&sk(&u));
    m
}

/// Spatial inertia about the frame origin from `[m, hx, hy, hz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`.
fn spatial_inertia(p: &[f64]) -> Matrix6<f64> {
    let h = Vector3::new(p[1], p[2], p[3]);
    let i = Matrix3::new(p[4], p[7], p[8], p[7], p[5], p[9], p[8], p[9], p[6]);
    let mut s = Matrix6::zeros();
    s.fixed_view_mut::<3, 3>(0, 0).copy_from(&i);
    s.fixed_view_mut::<3, 3>(0, 3).copy_from(&sk(&h));
    s.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&sk(&h).transpose());
    s.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(p[0] * Matrix3::identity()));
    s
}

/// Featherstone RNEA plus friction/rotor terms, on the robot's generic joints.
fn featherstone(
    robot: &Robot,
    theta: &DVector<f64>,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
) -> Vec<f64> {
    let qf = full_joint_positions(robot, q);
    let n = robot.joints.len();
    let mut qdf = vec![0.0; n];
    let mut qddf = vec![0.0; n];
    let mut rows = vec![None; n];
    let mut m = 0;
    for (i, j) in robot.joints.iter().enumerate() {
        if j.mode == JointMode::Modelled {
            qdf[i] = qd[m];
            qddf[i] = qdd[m];
            rows[i] = Some(m);
            m += 1;
        }
    }
    let g = robot.gravity;
    let mut xs = Vec::new();
    let mut v = Vec::new();
    let mut a = Vec::new();
    let mut f = Vec::new();
    let mut v_p = Vector6::zeros();
    let mut a_p = Vector6::new(0.0, 0.0, 0.0, -g.x, -g.y, -g.z);
    for (i, j) in robot.joints.iter().enumerate() {
        let rot = j.origin_rotation * axis_rotation(&j.axis, qf[i]);
        let x = xform(&rot, &j.origin_translation);
        let s = Vector6::new(j.axis.x, j.axis.y, j.axis.z, 0.0, 0.0, 0.0);
        let vi = x * v_p + s * qdf[i];
        let ai = x * a_p + s * qddf[i] + crm(&vi) * s * qdf[i];
        // Link inertia: given in the link frame; move it to the body frame.
        let lp = &theta.as_slice()[10 * i..10 * i + 10];
        let il = spatial_inertia(lp);
        let ib = match &j.link_frame {
            None => il,
            Some((r, p)) => {
                let xl = xform(r, p); // body -> link motion transform
                xl.transpose() * il * xl
            }
        };
        let fi = ib * ai + (-crm(&vi).transpose()) * ib * vi;
        xs.push(x);
        v.push(vi);
        a.push(ai);
        f.push(fi);
        v_p = vi;
        a_p = ai;
    }
    let mut tau = vec![0.0; m];
    for i in (0..n).rev() {
        let j = &robot.joints[i];
        let s = Vector6::new(j.axis.x, j.axis.y, j.axis.z, 0.0, 0.0, 0.0);
        if let Some(r) = rows[i] {
            tau[r] = s.dot(&f[i]);
        }
        if i > 0 {
            let up = xs[i].transpose() * f[i];
            f[i - 1] += up;
        }
    }
    // Friction and rotor terms, by name.
    let names = robot.parameter_names();
    let modelled = robot.modelled_joints();
    for (r, &ji) in modelled.iter().enumerate() {
        let get = |prefix: &str| {
            names
                .iter()
                .position(|n| *n == format!("{prefix}{}", ji + 1))
                .map(|k| theta[k])
                .unwrap_or(0.0)
        };
        let sgn = match robot.terms.coulomb_smoothing_rad_s {
            Some(eps) => (qd[r] / eps).tanh(),
            None => qd[r].signum() * if qd[r] == 0.0 { 0.0 } else { 1.0 },
        };
        tau[r] += get("fv") * qd[r] + get("fc") * sgn + get("fo") + get("Ia") * qdd[r];
        // The extended friction basis, written out from its definition.
        for (k, v) in [0.05, 0.2, 1.0].iter().enumerate() {
            tau[r] += get(&format!("fs{}_", k + 1)) * (qd[r] / v).tanh();
        }
        tau[r] += get("fq") * qd[r] * qd[r].abs();
    }
    tau
}

fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt();
    let den: f64 = b.iter().map(|y| y * y).sum::<f64>().sqrt().max(1e-300);
    num / den
}

fn check_against_featherstone(robot: &Robot, seed: u64) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = robot.n_modelled();
    let p = robot.parameter_count();
    let mut worst = 0.0f64;
    for trial in 0..50 {
        let theta = if trial == 0 {
            robot.standard_parameters()
        } else {
            random_theta(&mut rng, p)
        };
        let (q, qd, qdd) = random_state(&mut rng, n);
        let reference = featherstone(robot, &theta, &q, &qd, &qdd);
        let by_regressor = regressor(robot, &q, &qd, &qdd) * &theta;
        let by_rnea = rnea(robot, &theta, &q, &qd, &qdd, &robot.gravity);
        let e1 = rel_err(by_regressor.as_slice(), &reference);
        let e2 = rel_err(by_rnea.as_slice(), &reference);
        assert!(
            e1 < 1e-10,
            "regressor vs Featherstone: relative error {e1:e} (trial {trial})"
        );
        assert!(
            e2 < 1e-10,
            "rnea vs Featherstone: relative error {e2:e} (trial {trial})"
        );
        worst = worst.max(e1).max(e2);
    }
    worst
}

#[test]
fn regressor_matches_featherstone_on_dh_robots() {
    let robot = ur_like();
    println!(
        "standard DH, all joints: worst relative error {:.2e}",
        check_against_featherstone(&robot, 1)
    );
    let mut paper = robot.default_paper_selection();
    paper.lock_joint(0, 0.4);
    paper.lock_joint(1, -1.1);
    paper.lock_joint(2, 0.7);
    println!(
        "standard DH, joints 1-3 locked: worst relative error {:.2e}",
        check_against_featherstone(&paper, 2)
    );
    let two = planar_2r();
    println!(
        "modified DH planar 2R: worst relative error {:.2e}",
        check_against_featherstone(&two, 3)
    );
}

#[test]
fn regressor_matches_featherstone_on_ur10e_urdf() {
    let Some(mut robot) = ur10e() else { return };
    robot.terms.friction_offset = true;
    robot.terms.rotor_inertia = true;
    println!(
        "ur10e.urdf: worst relative error {:.2e}",
        check_against_featherstone(&robot, 4)
    );
    let mut paper = robot.default_paper_selection();
    paper.lock_joint(1, -0.9);
    println!(
        "ur10e.urdf, 1-3 locked: worst relative error {:.2e}",
        check_against_featherstone(&paper, 5)
    );
}

#[test]
fn standard_and_modified_dh_describe_the_same_arm() {
    // The planar 2R in standard DH: frames at the distal ends; COM shifted accordingly.
    let standard = r#"
name = "planar-2r-standard"
convention = "standard"
gravity = [0.0, -9.81, 0.0]
[terms]
viscous_friction = false
coulomb_friction = false
[[joint]]
name = "shoulder"
a = 0.5
alpha = 0.0
d = 0.0
mass = 2.0
com = [-0.25, 0.0, 0.0]
inertia = [0.002, 0.045, 0.045, 0.0, 0.0, 0.0]
[[joint]]
name = "elbow"
a = 0.4
alpha = 0.0
d = 0.0
mass = 1.2
com = [-0.2, 0.01, 0.0]
inertia = [0.001, 0.018, 0.018, 0.0, 0.0, 0.0]
"#;
    let s = Robot::from_dh_toml_str(standard, "standard.toml").unwrap();
    let mut m = planar_2r();
    m.terms = ModelTerms::rigid_body_only();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..20 {
        let (q, qd, qdd) = random_state(&mut rng, 2);
        let a = rnea(&s, &s.standard_parameters(), &q, &qd, &qdd, &s.gravity);
        let b = rnea(&m, &m.standard_parameters(), &q, &qd, &qdd, &m.gravity);
        assert!(rel_err(a.as_slice(), b.as_slice()) < 1e-12, "{a} vs {b}");
    }
}

// ---------------------------------------------------------------------------------
// Power balance.

/// Kinetic and potential energy from link velocities (geometric Jacobian from the
/// forward kinematics), independent of the Newton-Euler code.
fn energy(robot: &Robot, q: &[f64], qd: &[f64]) -> (f64, f64) {
    let frames = forward_kinematics(robot, q);
    let modelled = robot.modelled_joints();
    let mut ke = 0.0;
    let mut pe = 0.0;
    for (k, j) in robot.joints.iter().enumerate() {
        let (rk, pk) = &frames[k];
        let (lr, lp) = j
            .link_frame
            .unwrap_or((Matrix3::identity(), Vector3::zeros()));
        let c_world = pk + rk * (lr * j.inertial.com_m + lp);
        let ic_world = rk * lr * j.inertial.inertia_com * lr.transpose() * rk.transpose();
        let mut w = Vector3::zeros();
        let mut v = Vector3::zeros();
        for (r, &ji) in modelled.iter().enumerate() {
            if ji > k {
                break;
            }
            let (rj, pj) = &frames[ji];
            let z = rj * robot.joints[ji].axis.into_inner();
            w += z * qd[r];
            v += z.cross(&(c_world - pj)) * qd[r];
        }
        ke += 0.5 * j.inertial.mass_kg * v.norm_squared() + 0.5 * w.dot(&(ic_world * w));
        pe -= j.inertial.mass_kg * robot.gravity.dot(&c_world);
    }
    (ke, pe)
}

fn check_power_balance(robot: &Robot, seed: u64) -> f64 {
    let mut robot = robot.clone();
    robot.terms = ModelTerms::rigid_body_only();
    let theta = robot.standard_parameters();
    let n = robot.n_modelled();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // q(t) = q0 + sum_k a_k sin(w_k t + phi_k), three harmonics per joint.
    let params: Vec<[(f64, f64, f64); 3]> = (0..n)
        .map(|_| {
            std::array::from_fn(|_| {
                (
                    rng.gen_range(-0.6..0.6),
                    rng.gen_range(0.5..3.0),
                    rng.gen_range(0.0..std::f64::consts::TAU),
                )
            })
        })
        .collect();
    let q0: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.5..1.5)).collect();
    let state = |t: f64| {
        let mut q = q0.clone();
        let mut qd = vec![0.0; n];
        let mut qdd = vec![0.0; n];
        for i in 0..n {
            for &(a, w, ph) in &params[i] {
                q[i] += a * (w * t + ph).sin();
                qd[i] += a * w * (w * t + ph).cos();
                qdd[i] -= a * w * w * (w * t + ph).sin();
            }
        }
        (q, qd, qdd)
    };
    let total = |t: f64| {
        let (q, qd, _) = state(t);
        let (k, p) = energy(&robot, &q, &qd);
        k + p
    };
    let mut worst = 0.0f64;
    let h = 1e-4;
    for step in 0..40 {
        let t = 0.05 * step as f64;
        let (q, qd, qdd) = state(t);
        let de_dt = (-total(t + 2.0 * h) + 8.0 * total(t + h) - 8.0 * total(t - h)
            + total(t - 2.0 * h))
            / (12.0 * h);
        let tau = rnea(&robot, &theta, &q, &qd, &qdd, &robot.gravity);
        let power: f64 = tau.iter().zip(&qd).map(|(a, b)| a * b).sum();
        let scale: f64 = tau
            .iter()
            .zip(&qd)
            .map(|(a, b)| (a * b).abs())
            .sum::<f64>()
            .max(1e-9);
        let err = (de_dt - power).abs() / scale;
        assert!(
            err < 1e-7,
            "t={t}: dE/dt {de_dt} vs tau*qd {power} (relative {err:e})"
        );
        // Kinetic energy from the mass matrix equals the one from link velocities.
        let m = mass_matrix(&robot, &theta, &q);
        let qdv = DVector::from_column_slice(&qd);
        let ke_m = 0.5 * qdv.dot(&(&m * &qdv));
        let (ke, _) = energy(&robot, &q, &qd);
        assert!(
            (ke_m - ke).abs() <= 1e-10 * ke.abs().max(1e-9),
            "KE {ke} vs qd'Mqd/2 {ke_m}"
        );
        // M qdd + bias = rnea.
        let split = &m * DVector::from_column_slice(&qdd)
            + bias_forces(&robot, &theta, &q, &qd, &robot.gravity);
        assert!(rel_err(split.as_slice(), tau.as_slice()) < 1e-10);
        worst = worst.max(err);
    }
    worst
}

#[test]
fn power_balance_along_smooth_motions() {
    println!(
        "ur-like DH: worst relative power error {:.2e}",
        check_power_balance(&ur_like(), 11)
    );
    let mut paper = ur_like().default_paper_selection();
    paper.lock_joint(1, 0.8);
    println!(
        "ur-like DH, 1-3 locked: worst {:.2e}",
        check_power_balance(&paper, 12)
    );
    println!(
        "planar 2R: worst {:.2e}",
        check_power_balance(&planar_2r(), 13)
    );
    if let Some(r) = ur10e() {
        println!("ur10e.urdf: worst {:.2e}", check_power_balance(&r, 14));
    }
}

// ---------------------------------------------------------------------------------
// Base parameters.

fn check_base_reproduces_torques(robot: &Robot, base: &BaseParameters, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let states: Vec<_> = (0..30)
        .map(|_| random_state(&mut rng, robot.n_modelled()))
        .collect();
    let y = stack_regressors(
        robot,
        states
            .iter()
            .map(|(a, b, c)| (a.as_slice(), b.as_slice(), c.as_slice())),
    );
    let yb = base.project(&y);
    for _ in 0..5 {
        let theta = random_theta(&mut rng, robot.parameter_count());
        let beta = base.beta(&theta);
        let full = &y * &theta;
        let e = rel_err((&yb * &beta).as_slice(), full.as_slice());
        assert!(e < 1e-10, "Y theta vs Y_base beta: {e:e}");
        let eq = base.equivalent_standard(&beta);
        let e = rel_err((&y * &eq).as_slice(), full.as_slice());
        assert!(e < 1e-10, "Y theta_eq vs Y theta: {e:e}");
    }
}

#[test]
fn six_r_ur_type_arm_has_36_rigid_body_base_parameters() {
    let mut robot = ur_like();
    robot.terms = ModelTerms::rigid_body_only();
    let base = BaseParameters::compute(&robot, 7).unwrap();
    println!(
        "ur-like DH: {} base parameters; kept residual >= {:.2e}, dropped <= {:.2e}",
        base.count(),
        base.smallest_kept_residual,
        base.largest_dropped_residual
    );
    assert_eq!(base.count(), 36);
    check_base_reproduces_torques(&robot, &base, 8);
    // Friction: viscous + Coulomb + offset add 3 per joint; rotor inertia adds 4: joint
    // 1's is absorbed by I1zz, and joint 2's (axis perpendicular to axis 1) equals the
    // effect of an inertia `Ia2 * z2 z2^T` on link 2, so it joins link 2's groups.
    let full = ur_like();
    let base = BaseParameters::compute(&full, 7).unwrap();
    assert_eq!(base.count(), 36 + 18 + 4);
    check_base_reproduces_torques(&full, &base, 9);
    if let Some(mut r) = ur10e() {
        r.terms = ModelTerms::rigid_body_only();
        let b = BaseParameters::compute(&r, 7).unwrap();
        assert_eq!(b.count(), 36, "ur10e.urdf");
        check_base_reproduces_torques(&r, &b, 10);
    }
}

#[test]
fn planar_2r_grouping_matches_hand_derivation() {
    // Frames at the joints (modified DH), l1 = 0.5, gravity in the plane. By hand:
    // tau1 = (I1zz + I2zz + l1^2 m2 + 2 l1 (mx2 c2 - my2 s2)) qdd1 + ... + g((mx1 + l1 m2) c1 - my1 s1 + mx2 c12 - my2 s12),
    // so the base parameters are mx1 + l1 m2, my1, I1zz + l1^2 m2, mx2, my2, I2zz,
    // plus fv, fc of both joints; m1, mz*, Ixx.., products of inertia do not appear.
    let robot = planar_2r();
    let base = BaseParameters::compute(&robot, 3).unwrap();
    let names = robot.parameter_names();
    let idx = |n: &str| names.iter().position(|x| x == n).unwrap();
    let expected: Vec<Vec<(usize, f64)>> = vec![
        vec![(idx("mx1"), 1.0), (idx("m2"), 0.5)],
        vec![(idx("my1"), 1.0)],
        vec![(idx("I1zz"), 1.0), (idx("m2"), 0.25)],
        vec![(idx("mx2"), 1.0)],
        vec![(idx("my2"), 1.0)],
        vec![(idx("I2zz"), 1.0)],
        vec![(idx("fv1"), 1.0)],
        vec![(idx("fc1"), 1.0)],
        vec![(idx("fv2"), 1.0)],
        vec![(idx("fc2"), 1.0)],
    ];
    for e in base.expressions() {
        println!("{e}");
    }
    assert_eq!(base.count(), expected.len());
    for (i, exp) in expected.iter().enumerate() {
        assert_eq!(&base.terms(i), exp, "base parameter {}", i + 1);
    }
    assert_eq!(base.expressions()[2], "b3 = I1zz + 0.25*m2");
    check_base_reproduces_torques(&robot, &base, 4);
}

// ---------------------------------------------------------------------------------
// Firmware f32 model vs f64.

fn check_firmware<const N: usize>(robot: &Robot, theta: &DVector<f64>, seed: u64) -> f64 {
    let model = build_firmware_model::<N>(robot, theta).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut worst = 0.0f64;
    for _ in 0..200 {
        let (q, qd, qdd) = random_state(&mut rng, N);
        let f64_tau = rnea(robot, theta, &q, &qd, &qdd, &robot.gravity);
        let q32: [f32; N] = std::array::from_fn(|i| q[i] as f32);
        let qd32: [f32; N] = std::array::from_fn(|i| qd[i] as f32);
        let qdd32: [f32; N] = std::array::from_fn(|i| qdd[i] as f32);
        // Compare at the f32-rounded state so only arithmetic differs.
        let qr: Vec<f64> = q32.iter().map(|&x| x as f64).collect();
        let qdr: Vec<f64> = qd32.iter().map(|&x| x as f64).collect();
        let qddr: Vec<f64> = qdd32.iter().map(|&x| x as f64).collect();
        let reference = rnea(robot, theta, &qr, &qdr, &qddr, &robot.gravity);
        let tau32 = model.torques(&q32, &qd32, &qdd32);
        let got: Vec<f64> = tau32.iter().map(|&x| x as f64).collect();
        let e = rel_err(&got, reference.as_slice());
        assert!(
            e < 1e-5,
            "f32 vs f64 relative error {e:e}: {got:?} vs {reference}"
        );
        assert!(rel_err(f64_tau.as_slice(), reference.as_slice()) < 1e-5);
        worst = worst.max(e);
    }
    worst
}

#[test]
fn firmware_f32_model_matches_f64() {
    let robot = ur_like();
    let theta = robot.standard_parameters();
    println!(
        "ur-like, nominal, 6 joints: worst f32 relative error {:.2e}",
        check_firmware::<6>(&robot, &theta, 1)
    );
    let mut paper = robot.default_paper_selection();
    paper.lock_joint(0, 0.3);
    paper.lock_joint(1, -1.2);
    paper.lock_joint(2, 0.9);
    let theta = paper.standard_parameters();
    println!(
        "ur-like, 1-3 locked: worst {:.2e}",
        check_firmware::<3>(&paper, &theta, 2)
    );
    // The firmware evaluates the equivalent standard parameters of identified base parameters.
    let base = BaseParameters::compute(&paper, 5).unwrap();
    let eq = base.equivalent_standard(&base.beta(&theta));
    println!(
        "ur-like, 1-3 locked, equivalent standard: worst {:.2e}",
        check_firmware::<3>(&paper, &eq, 3)
    );
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    for _ in 0..20 {
        let (q, qd, qdd) = random_state(&mut rng, 3);
        let a = rnea(&paper, &eq, &q, &qd, &qdd, &paper.gravity);
        let b = rnea(&paper, &theta, &q, &qd, &qdd, &paper.gravity);
        assert!(rel_err(a.as_slice(), b.as_slice()) < 1e-10);
    }
    if let Some(r) = ur10e() {
        println!(
            "ur10e.urdf: worst {:.2e}",
            check_firmware::<6>(&r, &r.standard_parameters(), 4)
        );
    }
    assert!(build_firmware_model::<5>(&robot, &robot.standard_parameters()).is_err());
}

#[test]
fn extended_friction_basis_matches_its_definition_in_f64_and_f32() {
    let mut robot = ur_like();
    robot.terms.extended_friction = true;
    robot.terms.coulomb_smoothing_rad_s = Some(0.02);
    let names = robot.parameter_names();
    for name in ["fo4", "fs1_4", "fs3_4", "fq4"] {
        assert!(names.iter().any(|n| n == name), "no parameter {name}");
    }
    println!(
        "extended friction, all joints: worst relative error {:.2e}",
        check_against_featherstone(&robot, 11)
    );
    let mut paper = robot.default_paper_selection();
    paper.lock_joint(0, 0.3);
    paper.lock_joint(1, -1.2);
    paper.lock_joint(2, 0.9);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let theta = random_theta(&mut rng, paper.parameter_count());
    println!(
        "extended friction, 1-3 locked, f32: worst {:.2e}",
        check_firmware::<3>(&paper, &theta, 13)
    );
}

// ---------------------------------------------------------------------------------
// Bad input.

fn expect_error(result: Result<Robot, robot::RobotError>, line: usize, field: &str) {
    let e = result.expect_err("must fail");
    let text = e.to_string();
    println!("{text}");
    assert_eq!(e.line, Some(line), "{text}");
    assert!(
        e.field.contains(field),
        "field `{}` should mention `{field}`: {text}",
        e.field
    );
    assert!(text.starts_with("bad."), "{text}");
}

#[test]
fn bad_toml_names_file_line_and_field() {
    // Syntax error on line 3.
    expect_error(
        Robot::from_dh_toml_str(
            "name = \"x\"\nconvention = \"standard\"\ngravity = [0.0, 0.0,\n",
            "bad.toml",
        ),
        4,
        "gravity",
    );
    let good = std::fs::read_to_string(test_support::robots_dir().join("planar_2r.toml")).unwrap();
    let line_of = |text: &str, needle: &str, nth: usize| {
        text.lines()
            .enumerate()
            .filter(|(_, l)| l.trim_start().starts_with(needle))
            .nth(nth)
            .unwrap()
            .0
            + 1
    };
    // Negative mass in the second joint.
    let t = good.replacen("mass = 1.2", "mass = -1.2", 1);
    expect_error(
        Robot::from_dh_toml_str(&t, "bad.toml"),
        line_of(&t, "mass", 1),
        "joint[1].mass",
    );
    // Inertia not positive semi-definite.
    let t = good.replacen(
        "inertia = [0.001, 0.018, 0.018",
        "inertia = [0.001, -0.018, 0.018",
        1,
    );
    expect_error(
        Robot::from_dh_toml_str(&t, "bad.toml"),
        line_of(&t, "inertia", 1),
        "joint[1].inertia",
    );
    // Unknown field (typo).
    let t = good.replacen("qd_max = 4.0", "qdmax = 4.0", 1);
    expect_error(
        Robot::from_dh_toml_str(&t, "bad.toml"),
        line_of(&t, "qdmax", 0),
        "joint[1].qdmax",
    );
    // Wrong type.
    let t = good.replacen("a = 0.5", "a = \"half\"", 1);
    expect_error(
        Robot::from_dh_toml_str(&t, "bad.toml"),
        line_of(&t, "a = \"half\"", 0),
        "joint[1].a",
    );
    // Missing field: reported at the joint's block.
    let t = good.replacen("com = [0.2, 0.01, 0.0]\n", "", 1);
    let e = Robot::from_dh_toml_str(&t, "bad.toml").unwrap_err();
    println!("{e}");
    assert!(e.to_string().contains("com") && e.line.is_some(), "{e}");
    // q limits crossed.
    let t = good.replacen("q_max = 2.6", "q_max = -2.7", 1);
    expect_error(
        Robot::from_dh_toml_str(&t, "bad.toml"),
        line_of(&t, "q_max", 1),
        "joint[1].q_max",
    );
}

#[test]
fn bad_urdf_names_file_line_and_field() {
    let good = r#"<robot name="r">
  <link name="base"/>
  <joint name="j1" type="revolute">
    <parent link="base"/>
    <child link="l1"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="2"/>
  </joint>
  <link name="l1">
    <inertial>
      <origin xyz="0.1 0 0" rpy="0 0 0"/>
      <mass value="1.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
    </inertial>
  </link>
</robot>
"#;
    let r = Robot::from_urdf_str(good, "bad.urdf").unwrap();
    assert_eq!(r.dof(), 1);
    assert_eq!(r.joints[0].limits.q_max_rad, Some(1.0));
    // Unclosed element.
    let t = good.replace("    </inertial>\n", "");
    expect_error(Robot::from_urdf_str(&t, "bad.urdf"), 11, "inertial");
    assert!(
        Robot::from_urdf_str(&t, "bad.urdf")
            .unwrap_err()
            .message
            .contains("line 15")
    );
    // Negative mass: reported at the link.
    let t = good.replace("<mass value=\"1.0\"/>", "<mass value=\"-1.0\"/>");
    expect_error(Robot::from_urdf_str(&t, "bad.urdf"), 10, "mass");
    // Zero axis: reported at the joint.
    let t = good.replace("<axis xyz=\"0 0 1\"/>", "<axis xyz=\"0 0 0\"/>");
    expect_error(Robot::from_urdf_str(&t, "bad.urdf"), 3, "axis");
    // Unsupported joint type.
    let t = good.replace("type=\"revolute\"", "type=\"prismatic\"");
    expect_error(Robot::from_urdf_str(&t, "bad.urdf"), 3, "type");
    // A number that is not one.
    let t = good.replace("izz=\"0.01\"", "izz=\"abc\"");
    expect_error(Robot::from_urdf_str(&t, "bad.urdf"), 14, "inertia> izz");
    // Loading from a file names the path.
    let dir = std::env::temp_dir().join(format!("dyn-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("broken.urdf");
    std::fs::write(&path, good.replace("    </inertial>\n", "")).unwrap();
    let e = Robot::load(&path).unwrap_err();
    assert!(e.to_string().contains("broken.urdf:11"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
