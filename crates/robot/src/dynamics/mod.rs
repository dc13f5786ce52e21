//! Rigid-body inverse dynamics (f64): recursive Newton-Euler, the regressor linear in
//! the standard parameters, mass matrix, bias forces and friction.
//!
//! Joint vectors `q`, `qd`, `qdd` and torques hold the *modelled* joints only
//! ([`Robot::modelled_joints`]); locked joints sit at their fixed positions with zero
//! velocity. `theta` is the standard parameter vector in [`Robot::parameter_layout`]
//! order (per link `[m, mx, my, mz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]` in the link frame,
//! inertia about the link frame origin; then per modelled joint the friction/rotor
//! terms of [`crate::ModelTerms`]).
//!
//! The model: `tau = M(q) qdd + c(q, qd) + g(q) + fv*qd + fc*sgn(qd) + fo + Ia*qdd`
//! `= Y(q, qd, qdd) * theta`.
//!
//! The functions panic when a vector's length differs from the number of modelled
//! joints (or `theta` from the layout): a programming error, never a data error; input
//! files are validated when the robot is loaded.
//!
//! API: [`regressor`] (one sample, `n_modelled x p`), [`stack_regressors`],
//! [`rnea`], [`mass_matrix`], [`bias_forces`], [`friction_torques`],
//! [`forward_kinematics`], [`full_joint_positions`].
use crate::{JointMode, JointParameter, PARAMETERS_PER_LINK, Robot, axis_rotation};
use nalgebra::{DMatrix, DVector, Matrix3, SMatrix, Vector3};

pub mod firmware_model;

type Mat10 = SMatrix<f64, 10, 10>;

/// Cross-product matrix `[v]x`.
#[inline]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Positions of all joints of the robot: modelled ones from `q`, locked ones fixed.
pub fn full_joint_positions(robot: &Robot, q: &[f64]) -> Vec<f64> {
    let mut it = q.iter();
    robot
        .joints
        .iter()
        .map(|j| match j.mode {
            JointMode::Modelled => *it.next().expect("q shorter than the modelled joints"),
            JointMode::Locked { q_rad } => q_rad,
        })
        .collect()
}

/// Body frames in the base frame (rotation, origin [m]) for modelled positions `q`.
pub fn forward_kinematics(robot: &Robot, q: &[f64]) -> Vec<(Matrix3<f64>, Vector3<f64>)> {
    let qf = full_joint_positions(robot, q);
    let mut r = Matrix3::identity();
    let mut p = Vector3::zeros();
    let mut out = Vec::with_capacity(qf.len());
    for (j, &qi) in robot.joints.iter().zip(&qf) {
        p += r * j.origin_translation;
        r = r * j.origin_rotation * axis_rotation(&j.axis, qi);
        out.push((r, p));
    }
    out
}

/// Per-call precomputation: joint motion, link-to-body parameter maps.
struct Chain {
    /// Parent-to-body rotation and translation per joint at the current state.
    rot: Vec<Matrix3<f64>>,
    pos: Vec<Vector3<f64>>,
    axis: Vec<Vector3<f64>>,
    /// Body velocities/accelerations (angular velocity, angular acceleration, linear acceleration of the origin incl. gravity).
    w: Vec<Vector3<f64>>,
    wd: Vec<Vector3<f64>>,
    acc: Vec<Vector3<f64>>,
}

struct Statics {
    /// link->body map of standard parameters, per link (None = identity).
    to_body: Vec<Option<Mat10>>,
    /// Row of each joint in the output (None for locked joints).
    row: Vec<Option<usize>>,
    first_modelled: usize,
    n_modelled: usize,
    /// Per-joint parameter kinds of the layout.
    kinds: Vec<JointParameter>,
}

impl Statics {
    fn new(robot: &Robot) -> Statics {
        let to_body = robot
            .joints
            .iter()
            .map(|j| {
                j.link_frame.as_ref().map(|_| {
                    let mut a = Mat10::zeros();
                    for c in 0..10 {
                        let mut e = [0.0; 10];
                        e[c] = 1.0;
                        let t = j.link_to_body(&e);
                        for r in 0..10 {
                            a[(r, c)] = t[r];
                        }
                    }
                    a
                })
            })
            .collect();
        let mut row = Vec::with_capacity(robot.joints.len());
        let mut n = 0;
        for j in &robot.joints {
            if j.mode == JointMode::Modelled {
                row.push(Some(n));
                n += 1;
            } else {
                row.push(None);
            }
        }
        let first_modelled = row.iter().position(|r| r.is_some()).unwrap_or(row.len());
        Statics {
            to_body,
            row,
            first_modelled,
            n_modelled: n,
            kinds: robot.terms.joint_parameter_kinds(),
        }
    }
}

impl Chain {
    fn with_capacity(n: usize) -> Chain {
        Chain {
            rot: Vec::with_capacity(n),
            pos: Vec::with_capacity(n),
            axis: Vec::with_capacity(n),
            w: Vec::with_capacity(n),
            wd: Vec::with_capacity(n),
            acc: Vec::with_capacity(n),
        }
    }

    fn clear(&mut self) {
        self.rot.clear();
        self.pos.clear();
        self.axis.clear();
        self.w.clear();
        self.wd.clear();
        self.acc.clear();
    }
}

fn forward_pass(
    robot: &Robot,
    st: &Statics,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &Vector3<f64>,
) -> Chain {
    let mut c = Chain::with_capacity(robot.joints.len());
    forward_pass_into(robot, st, q, qd, qdd, gravity, &mut c);
    c
}

fn forward_pass_into(
    robot: &Robot,
    st: &Statics,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &Vector3<f64>,
    c: &mut Chain,
) {
    assert_eq!(q.len(), st.n_modelled, "q must hold the modelled joints");
    assert_eq!(qd.len(), st.n_modelled, "qd must hold the modelled joints");
    assert_eq!(
        qdd.len(),
        st.n_modelled,
        "qdd must hold the modelled joints"
    );
    c.clear();
    let (mut w, mut wd, mut acc) = (Vector3::zeros(), Vector3::zeros(), -gravity);
    for (i, j) in robot.joints.iter().enumerate() {
        let (qi, qdi, qddi) = match (st.row[i], j.mode) {
            (Some(r), _) => (q[r], qd[r], qdd[r]),
            (None, JointMode::Locked { q_rad }) => (q_rad, 0.0, 0.0),
            (None, JointMode::Modelled) => unreachable!(),
        };
        let r = j.origin_rotation * axis_rotation(&j.axis, qi);
        let p = j.origin_translation;
        let a = j.axis.into_inner();
        let rt = r.transpose();
        let acc_new = rt * (acc + wd.cross(&p) + w.cross(&w.cross(&p)));
        let w_in = rt * w;
        let w_new = w_in + a * qdi;
        let wd_new = rt * wd + w_in.cross(&(a * qdi)) + a * qddi;
        w = w_new;
        wd = wd_new;
        acc = acc_new;
        c.rot.push(r);
        c.pos.push(p);
        c.axis.push(a);
        c.w.push(w);
        c.wd.push(wd);
        c.acc.push(acc);
    }
}

/// The regressor rows for one state: `tau = Y * theta`, `n_modelled x p`.
pub fn regressor(robot: &Robot, q: &[f64], qd: &[f64], qdd: &[f64]) -> DMatrix<f64> {
    let mut ws = Workspace::new(robot);
    let mut y = DMatrix::zeros(ws.st.n_modelled, robot.parameter_count());
    regressor_into(robot, &mut ws, (q, qd, qdd), &mut y, 0);
    y
}

/// Alias of [`regressor`] (the rows of one sample, ready to stack).
pub fn regressor_row_block(robot: &Robot, q: &[f64], qd: &[f64], qdd: &[f64]) -> DMatrix<f64> {
    regressor(robot, q, qd, qdd)
}

/// Reusable per-robot data and buffers for evaluating many samples.
struct Workspace {
    st: Statics,
    chain: Chain,
}

impl Workspace {
    fn new(robot: &Robot) -> Workspace {
        Workspace {
            st: Statics::new(robot),
            chain: Chain::with_capacity(robot.joints.len()),
        }
    }
}

fn regressor_into(
    robot: &Robot,
    ws: &mut Workspace,
    (q, qd, qdd): (&[f64], &[f64], &[f64]),
    y: &mut DMatrix<f64>,
    row0: usize,
) {
    let Workspace { st, chain: c } = ws;
    let st = &*st;
    forward_pass_into(robot, st, q, qd, qdd, &robot.gravity, c);
    let n = robot.joints.len();
    // Y[j, link k] = u . n_k + v . f_k, where (f_k, n_k) is link k's wrench regressor
    // (force, moment about the origin; body frame k) and (u, v) is joint j's unit twist
    // seen in frame k: u = axis_j, v = velocity of origin k for a unit rate of joint j.
    // With f_k = [acc | [wd]x + [w]x^2 | 0] and n_k = [0 | -[acc]x | L(wd) + [w]x L(w)]:
    //   m: v.acc;  h: v x wd + (v x w) x w - u x acc;  I: L(wd)^T u + L(w)^T (u x w).
    for j in st.first_modelled..n {
        let Some(r) = st.row[j] else { continue };
        let mut u = c.axis[j];
        let mut v = Vector3::zeros();
        for k in j..n {
            if k > j {
                let rt = c.rot[k].transpose();
                v = rt * (v + u.cross(&c.pos[k]));
                u = rt * u;
            }
            let (w, wd, acc) = (&c.w[k], &c.wd[k], &c.acc[k]);
            let hcol = v.cross(wd) + v.cross(w).cross(w) - u.cross(acc);
            let uw = u.cross(w);
            let row = [
                v.dot(acc),
                hcol.x,
                hcol.y,
                hcol.z,
                wd.x * u.x + w.x * uw.x,
                wd.y * u.y + w.y * uw.y,
                wd.z * u.z + w.z * uw.z,
                wd.y * u.x + wd.x * u.y + w.y * uw.x + w.x * uw.y,
                wd.z * u.x + wd.x * u.z + w.z * uw.x + w.x * uw.z,
                wd.z * u.y + wd.y * u.z + w.z * uw.y + w.y * uw.z,
            ];
            let col0 = PARAMETERS_PER_LINK * k;
            match &st.to_body[k] {
                None => {
                    for (cc, x) in row.iter().enumerate() {
                        y[(row0 + r, col0 + cc)] = *x;
                    }
                }
                Some(a) => {
                    for cc in 0..PARAMETERS_PER_LINK {
                        let mut acc_l = 0.0;
                        for (rr, x) in row.iter().enumerate() {
                            acc_l += x * a[(rr, cc)];
                        }
                        y[(row0 + r, col0 + cc)] = acc_l;
                    }
                }
            }
        }
    }
    let layout_kinds = &st.kinds;
    let base = PARAMETERS_PER_LINK * n;
    let nk = layout_kinds.len();
    for r in 0..st.n_modelled {
        for (s, kind) in layout_kinds.iter().enumerate() {
            y[(row0 + r, base + r * nk + s)] =
                kind.column(qd[r], qdd[r], robot.terms.coulomb_sign(qd[r]));
        }
    }
}

/// Stacks the regressors of many states (`(q, qd, qdd)` per sample) into one
/// `(samples * n_modelled) x p` matrix, sample-major.
pub fn stack_regressors<'a, I>(robot: &Robot, states: I) -> DMatrix<f64>
where
    I: IntoIterator<Item = (&'a [f64], &'a [f64], &'a [f64])>,
{
    let states: Vec<_> = states.into_iter().collect();
    let mut ws = Workspace::new(robot);
    let n_modelled = ws.st.n_modelled;
    let mut y = DMatrix::zeros(states.len() * n_modelled, robot.parameter_count());
    for (s, &state) in states.iter().enumerate() {
        regressor_into(robot, &mut ws, state, &mut y, s * n_modelled);
    }
    y
}

/// Body-frame standard parameters of every link from `theta`.
fn body_parameters(robot: &Robot, theta: &DVector<f64>) -> Vec<[f64; 10]> {
    assert_eq!(
        theta.len(),
        robot.parameter_count(),
        "theta does not match the parameter layout"
    );
    robot
        .joints
        .iter()
        .enumerate()
        .map(|(k, j)| {
            let mut p = [0.0; 10];
            p.copy_from_slice(
                &theta.as_slice()[PARAMETERS_PER_LINK * k..PARAMETERS_PER_LINK * (k + 1)],
            );
            j.link_to_body(&p)
        })
        .collect()
}

fn rigid_rnea(
    robot: &Robot,
    st: &Statics,
    phi: &[[f64; 10]],
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &Vector3<f64>,
) -> DVector<f64> {
    let c = forward_pass(robot, st, q, qd, qdd, gravity);
    let n = robot.joints.len();
    let mut tau = DVector::zeros(st.n_modelled);
    let mut f_child = Vector3::zeros();
    let mut n_child = Vector3::zeros();
    for k in (st.first_modelled..n).rev() {
        let p = &phi[k];
        let (w, wd, acc) = (&c.w[k], &c.wd[k], &c.acc[k]);
        let h = Vector3::new(p[1], p[2], p[3]);
        let i = crate::inertia_matrix(&[p[4], p[5], p[6], p[7], p[8], p[9]]);
        let mut f = p[0] * acc + wd.cross(&h) + w.cross(&w.cross(&h));
        let mut mo = i * wd + w.cross(&(i * w)) + h.cross(acc);
        if k + 1 < n {
            let rf = c.rot[k + 1] * f_child;
            f += rf;
            mo += c.rot[k + 1] * n_child + c.pos[k + 1].cross(&rf);
        }
        if let Some(r) = st.row[k] {
            tau[r] = c.axis[k].dot(&mo);
        }
        f_child = f;
        n_child = mo;
    }
    tau
}

fn joint_term(robot: &Robot, theta: &DVector<f64>, m: usize, kind: JointParameter) -> f64 {
    robot
        .parameter_layout()
        .joint_index(m, kind)
        .map(|i| theta[i])
        .unwrap_or(0.0)
}

/// Friction torques of the modelled joints at speeds `qd` [rad/s]: every per-joint term
/// in [`Robot::terms`] except the rotor inertia.
pub fn friction_torques(robot: &Robot, theta: &DVector<f64>, qd: &[f64]) -> DVector<f64> {
    let kinds = robot.terms.joint_parameter_kinds();
    DVector::from_iterator(
        qd.len(),
        qd.iter().enumerate().map(|(m, &v)| {
            kinds
                .iter()
                .filter(|&&k| k != JointParameter::RotorInertia)
                .map(|&k| {
                    joint_term(robot, theta, m, k) * k.column(v, 0.0, robot.terms.coulomb_sign(v))
                })
                .sum::<f64>()
        }),
    )
}

/// Full inverse dynamics `tau = M qdd + c + g + friction + Ia*qdd` by recursive
/// Newton-Euler (computed directly from `theta`, not through the regressor), with the
/// given gravity vector [m/s^2, base frame].
pub fn rnea(
    robot: &Robot,
    theta: &DVector<f64>,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &Vector3<f64>,
) -> DVector<f64> {
    let st = Statics::new(robot);
    let phi = body_parameters(robot, theta);
    let mut tau = rigid_rnea(robot, &st, &phi, q, qd, qdd, gravity);
    tau += friction_torques(robot, theta, qd);
    for (m, a) in qdd.iter().enumerate() {
        tau[m] += joint_term(robot, theta, m, JointParameter::RotorInertia) * a;
    }
    tau
}

/// Joint-space mass matrix `M(q)` (modelled joints, including reflected rotor
/// inertia when modelled), column by column from the Newton-Euler.
pub fn mass_matrix(robot: &Robot, theta: &DVector<f64>, q: &[f64]) -> DMatrix<f64> {
    let st = Statics::new(robot);
    let phi = body_parameters(robot, theta);
    let n = st.n_modelled;
    let zero = vec![0.0; n];
    let mut m = DMatrix::zeros(n, n);
    for c in 0..n {
        let mut e = vec![0.0; n];
        e[c] = 1.0;
        let col = rigid_rnea(robot, &st, &phi, q, &zero, &e, &Vector3::zeros());
        m.set_column(c, &col);
        m[(c, c)] += joint_term(robot, theta, c, JointParameter::RotorInertia);
    }
    // Symmetric by construction; remove rounding asymmetry.
    let mt = m.transpose();
    (m + mt) * 0.5
}

/// Bias forces `c(q, qd) + g(q)` (Coriolis, centrifugal, gravity; no friction).
pub fn bias_forces(
    robot: &Robot,
    theta: &DVector<f64>,
    q: &[f64],
    qd: &[f64],
    gravity: &Vector3<f64>,
) -> DVector<f64> {
    let st = Statics::new(robot);
    let phi = body_parameters(robot, theta);
    let zero = vec![0.0; st.n_modelled];
    rigid_rnea(robot, &st, &phi, q, qd, &zero, gravity)
}
