//! URDF trees: chains chosen by base and tip link with the other branches held fixed,
//! checked against Pinocchio's RNEA on public arms with grippers (fixture written by
//! `scripts/make_pinocchio_fixture.py`), and the hostile trees (loops, doubled joints,
//! several roots, size limits) refused by name.
use robot::dynamics::firmware_model::FirmwareModel;
use robot::dynamics::rnea;
use robot::{ChainSelection, MAX_URDF_JOINTS, ModelTerms, Robot, UrdfFriction};
use std::path::{Path, PathBuf};

#[path = "support/urdf_chain.rs"]
mod urdf_chain;
use urdf_chain::chain_urdf;

fn fixture_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/pinocchio")
}

/// One fixture robot: its chain selection and 500 states with Pinocchio's torques.
struct Case {
    name: String,
    urdf: PathBuf,
    selection: ChainSelection,
    chain_joints: Vec<String>,
    /// Rows of q, qd, qdd, tau (n each).
    rows: Vec<Vec<f64>>,
}

fn load_case(name: &str) -> Case {
    let dir = fixture_dir();
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join(format!("{name}.json"))).unwrap())
            .unwrap();
    let side = meta["side_joints"].as_object().unwrap();
    let selection = ChainSelection {
        base_link: Some(meta["base_link"].as_str().unwrap().to_string()),
        tip_link: Some(meta["tip_link"].as_str().unwrap().to_string()),
        side_joint_positions: side
            .iter()
            .map(|(k, v)| (k.clone(), v.as_f64().unwrap()))
            .collect(),
        ..ChainSelection::default()
    };
    let chain_joints = meta["chain_joints"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    let text = std::fs::read_to_string(dir.join(format!("{name}.csv"))).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), meta["states"].as_u64().unwrap() as usize);
    Case {
        name: name.into(),
        urdf: dir.join(meta["urdf"].as_str().unwrap()),
        selection,
        chain_joints,
        rows,
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Worst relative error over the fixture's states of our f64 RNEA and of the firmware's
/// f32 model, each `|tau - tau_pinocchio|_2 / |tau_pinocchio|_2` (the torque vector's
/// Euclidean norm).
fn check_case(name: &str) -> (f64, f64) {
    let case = load_case(name);
    let loaded = Robot::load_chain(&case.urdf, &case.selection)
        .unwrap_or_else(|e| panic!("{}: {e}", case.name));
    let mut robot = loaded.robot;
    let names: Vec<&str> = robot.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(names, case.chain_joints, "{}: chain joints", case.name);
    // Pinocchio's RNEA is the rigid body alone (no friction from <dynamics>).
    robot.terms = ModelTerms::rigid_body_only();
    let theta = robot.standard_parameters();
    let firmware = FirmwareModel::build(&robot, &theta).unwrap();
    let n = robot.dof();
    let (mut worst64, mut worst32) = (0.0f64, 0.0f64);
    for row in &case.rows {
        assert_eq!(row.len(), 4 * n);
        let (q, qd, qdd, reference) =
            (&row[..n], &row[n..2 * n], &row[2 * n..3 * n], &row[3 * n..]);
        let scale = norm(reference);
        assert!(scale > 1e-3, "{name}: a state with almost no torque");
        let ours = rnea(&robot, &theta, q, qd, qdd, &robot.gravity);
        let d64: Vec<f64> = ours.iter().zip(reference).map(|(a, b)| a - b).collect();
        worst64 = worst64.max(norm(&d64) / scale);
        let f32_tau = firmware.torques(q, qd, qdd);
        let d32: Vec<f64> = f32_tau.iter().zip(reference).map(|(a, b)| a - b).collect();
        worst32 = worst32.max(norm(&d32) / scale);
    }
    println!(
        "{name}: {} states, {n} joints: f64 RNEA worst relative error {worst64:.3e}, firmware f32 {worst32:.3e} (|dtau|_2 / |tau|_2)",
        case.rows.len()
    );
    (worst64, worst32)
}

#[test]
fn panda_with_fingers_locked_matches_pinocchio() {
    let (e64, e32) = check_case("panda");
    assert!(e64 <= 1e-9, "f64 {e64:.3e}");
    assert!(e32 <= 1e-5, "f32 {e32:.3e}");
}

#[test]
fn kinova_jaco_with_gripper_matches_pinocchio() {
    let (e64, e32) = check_case("kinova_j2s6s200");
    assert!(e64 <= 1e-9, "f64 {e64:.3e}");
    assert!(e32 <= 1e-5, "f32 {e32:.3e}");
}

#[test]
fn z1_with_gripper_jaw_held_matches_pinocchio() {
    let (e64, e32) = check_case("z1_gripper");
    assert!(e64 <= 1e-9, "f64 {e64:.3e}");
    assert!(e32 <= 1e-5, "f32 {e32:.3e}");
}

/// A gripper whose second knuckle and inner finger follow the driven knuckle through
/// `<mimic>` (multiplier -1, and 1 with an offset): with the master held at 0.62 rad the
/// followers stand at -0.62 and 0.72 rad, and the arm's torques equal Pinocchio's (its
/// URDF reader with `mimic=True`) within 1e-6 N·m at every state. Reading the followers
/// at 0 instead (the `<mimic>` ignored) is off by more than 1e-3 N·m.
#[test]
fn mimic_joints_follow_their_master_as_in_pinocchio() {
    let case = load_case("mimic_gripper");
    let loaded = Robot::load_chain(&case.urdf, &case.selection).unwrap();
    let mut held: Vec<(String, f64)> = loaded
        .folded
        .iter()
        .map(|f| (f.name.clone(), f.position))
        .collect();
    held.sort_by(|a, b| a.0.cmp(&b.0));
    let expect = [
        ("finger_joint", 0.62),
        ("left_inner_finger_joint", 0.72),
        ("right_knuckle_joint", -0.62),
    ];
    assert_eq!(held.len(), expect.len(), "{held:?}");
    for ((n, q), (en, eq)) in held.iter().zip(expect) {
        assert!(n == en && (q - eq).abs() < 1e-15, "{held:?}");
    }
    let mut robot = loaded.robot;
    robot.terms = ModelTerms::rigid_body_only();
    let theta = robot.standard_parameters();
    // The same arm with the <mimic> elements removed: followers at 0.
    let text = std::fs::read_to_string(&case.urdf).unwrap();
    let plain: String = text
        .lines()
        .filter(|l| !l.contains("<mimic"))
        .map(|l| format!("{l}\n"))
        .collect();
    let mut unfollowed = Robot::parse_chain(&plain, Path::new("plain.urdf"), &case.selection)
        .unwrap()
        .robot;
    unfollowed.terms = ModelTerms::rigid_body_only();
    let theta_plain = unfollowed.standard_parameters();
    let n = robot.dof();
    let (mut worst, mut worst_plain) = (0.0f64, 0.0f64);
    for row in &case.rows {
        let (q, qd, qdd, reference) =
            (&row[..n], &row[n..2 * n], &row[2 * n..3 * n], &row[3 * n..]);
        let ours = rnea(&robot, &theta, q, qd, qdd, &robot.gravity);
        let other = rnea(&unfollowed, &theta_plain, q, qd, qdd, &unfollowed.gravity);
        for j in 0..n {
            worst = worst.max((ours[j] - reference[j]).abs());
            worst_plain = worst_plain.max((other[j] - reference[j]).abs());
        }
    }
    println!(
        "mimic_gripper: {} states: worst |tau - tau_pinocchio| {worst:.3e} N·m; followers at 0: {worst_plain:.3e} N·m",
        case.rows.len()
    );
    assert!(worst <= 1e-6, "{worst:e} N·m");
    assert!(worst_plain > 1e-3, "{worst_plain:e} N·m");
    // A follower given its own position (--side-joint) is held there instead.
    let own = Robot::load_chain(
        &case.urdf,
        &ChainSelection {
            side_joint_positions: vec![
                ("finger_joint".into(), 0.62),
                ("right_knuckle_joint".into(), 0.1),
            ],
            ..case.selection.clone()
        },
    )
    .unwrap();
    let at =
        |l: &robot::LoadedRobot, n: &str| l.folded.iter().find(|f| f.name == n).map(|f| f.position);
    assert_eq!(at(&own, "right_knuckle_joint"), Some(0.1));
    assert_eq!(at(&own, "left_inner_finger_joint"), Some(0.72));
    // A chain joint or a branch that follows the chain, a master that is missing or
    // follows a joint itself, are refused by name.
    let edited = |from: &str, to: &str| {
        assert!(text.contains(from), "{from}");
        Robot::parse_chain(
            &text.replacen(from, to, 1),
            Path::new("edited.urdf"),
            &case.selection,
        )
        .unwrap_err()
        .to_string()
    };
    for (from, to, what) in [
        (
            "mimic joint=\"finger_joint\" multiplier=\"-1\"",
            "mimic joint=\"nothing\" multiplier=\"-1\"",
            "no joint \"nothing\" to follow",
        ),
        (
            "mimic joint=\"finger_joint\" multiplier=\"-1\"",
            "mimic joint=\"j2\" multiplier=\"-1\"",
            "follows joint \"j2\" of the chain",
        ),
        (
            "mimic joint=\"finger_joint\" multiplier=\"1\"",
            "mimic joint=\"right_knuckle_joint\" multiplier=\"1\"",
            "which follows a joint itself",
        ),
        (
            "<limit lower=\"-2.8\" upper=\"2.8\" effort=\"100\" velocity=\"3\"/>\n  </joint>\n  <link name=\"l3\">",
            "<limit lower=\"-2.8\" upper=\"2.8\" effort=\"100\" velocity=\"3\"/>\n<mimic joint=\"j1\"/>  </joint>\n  <link name=\"l3\">",
            "a chain joint that follows joint \"j1\"",
        ),
        (
            "multiplier=\"-1\"",
            "multiplier=\"x\"",
            "`x` is not a number",
        ),
    ] {
        let e = edited(from, to);
        assert!(e.contains("edited.urdf") && e.contains(what), "{to}: {e}");
    }
}

/// `<dynamics damping friction>` are left out of the nominal model by default (as in
/// Pinocchio's RNEA: the rigid body alone) and taken as the viscous and Coulomb friction
/// when chosen; the torques then differ by exactly `damping * qd + friction * sign(qd)`.
#[test]
fn urdf_damping_and_friction_enter_the_nominal_torque_only_when_chosen() {
    let path = test_support::robots_dir().join("default.urdf");
    let left_out = Robot::load(&path).unwrap();
    let chosen = Robot::load_chain(
        &path,
        &ChainSelection {
            urdf_friction: UrdfFriction::Nominal,
            ..ChainSelection::default()
        },
    )
    .unwrap()
    .robot;
    // default.urdf gives every joint damping 6.0 and friction 5.0 (its first joint at least).
    assert_eq!(chosen.joints[0].friction.viscous_nm_s_rad, 6.0);
    assert_eq!(chosen.joints[0].friction.coulomb_nm, 5.0);
    assert!(
        left_out
            .joints
            .iter()
            .all(|j| j.friction.viscous_nm_s_rad == 0.0 && j.friction.coulomb_nm == 0.0)
    );
    let (q, qd, qdd) = (
        [0.3, -1.1, 0.7, 0.2, -0.4, 1.0],
        [0.5, -0.8, 0.0, 1.2, -0.3, 0.9],
        [1.0, -2.0, 0.5, 0.0, 3.0, -1.0],
    );
    let a = rnea(
        &left_out,
        &left_out.standard_parameters(),
        &q,
        &qd,
        &qdd,
        &left_out.gravity,
    );
    let b = rnea(
        &chosen,
        &chosen.standard_parameters(),
        &q,
        &qd,
        &qdd,
        &chosen.gravity,
    );
    for (k, j) in chosen.joints.iter().enumerate() {
        let expect = j.friction.viscous_nm_s_rad * qd[k]
            + j.friction.coulomb_nm * qd[k].signum() * (qd[k] != 0.0) as u8 as f64;
        assert!(
            (b[k] - a[k] - expect).abs() < 1e-9,
            "joint {k}: {} vs {expect}",
            b[k] - a[k]
        );
    }
}

#[test]
fn panda_fingers_are_folded_with_a_warning_and_the_finger_position_matters() {
    let case = load_case("panda");
    let loaded = Robot::load_chain(&case.urdf, &case.selection).unwrap();
    let names: Vec<&str> = loaded.folded.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names.len(), 2, "{:?}", loaded.folded);
    assert!(names.contains(&"panda_finger_joint1") && names.contains(&"panda_finger_joint2"));
    for f in &loaded.folded {
        assert_eq!(f.joint_type, "prismatic");
        assert_eq!(f.carried_by.as_deref(), Some("panda_hand"));
    }
    let warning = loaded.warning().unwrap();
    assert!(
        warning.contains("panda_finger_joint1 (prismatic) at 0.02 m"),
        "{warning}"
    );
    // The fingers' positions move their mass: the hand's body differs from fingers at 0.
    let at_zero = Robot::load_chain(
        &case.urdf,
        &ChainSelection {
            side_joint_positions: Vec::new(),
            ..case.selection.clone()
        },
    )
    .unwrap();
    let last = |r: &Robot| r.joints.last().unwrap().inertial;
    assert_eq!(last(&at_zero.robot).mass_kg, last(&loaded.robot).mass_kg);
    assert_ne!(last(&at_zero.robot).com_m, last(&loaded.robot).com_m);
    // Without a tip the two fingers are the candidate tips, listed by name.
    let e = Robot::load(&case.urdf).unwrap_err();
    let s = e.to_string();
    assert!(
        s.contains("panda.urdf")
            && s.contains("\"panda_leftfinger\"")
            && s.contains("\"panda_rightfinger\"")
            && s.contains("--tip-link"),
        "{s}"
    );
    // A chain through a prismatic finger is refused by name.
    let e = Robot::load_chain(
        &case.urdf,
        &ChainSelection {
            tip_link: Some("panda_leftfinger".into()),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        e.field.contains("panda_finger_joint1")
            && e.message.contains("prismatic")
            && e.line.is_some(),
        "{e}"
    );
    // Unknown names and out-of-range positions name what is wrong.
    for (sel, what) in [
        (
            ChainSelection {
                tip_link: Some("no_such_link".into()),
                ..Default::default()
            },
            "no_such_link",
        ),
        (
            ChainSelection {
                side_joint_positions: vec![("panda_finger_joint1".into(), 0.5)],
                ..case.selection.clone()
            },
            "outside the joint's limits",
        ),
        (
            ChainSelection {
                side_joint_positions: vec![("panda_joint3".into(), 0.1)],
                ..case.selection.clone()
            },
            "--lock",
        ),
        (
            ChainSelection {
                side_joint_positions: vec![("fingerjoint".into(), 0.0)],
                ..case.selection.clone()
            },
            "fingerjoint",
        ),
    ] {
        let e = Robot::load_chain(&case.urdf, &sel).unwrap_err().to_string();
        assert!(e.contains("panda.urdf") && e.contains(what), "{e}");
    }
}

#[test]
fn a_base_link_below_the_root_sees_gravity_in_its_own_frame() {
    // The Panda from its third link: gravity turns with joints 1 and 2's held positions,
    // and the torques equal those of the full arm's joints 3-7 with 1 and 2 locked there.
    let case = load_case("panda");
    let (q1, q2) = (0.7, -0.4);
    let mut side = case.selection.side_joint_positions.clone();
    side.push(("panda_joint1".into(), q1));
    side.push(("panda_joint2".into(), q2));
    let sub = Robot::load_chain(
        &case.urdf,
        &ChainSelection {
            base_link: Some("panda_link2".into()),
            side_joint_positions: side,
            ..case.selection.clone()
        },
    )
    .unwrap();
    assert_eq!(sub.robot.dof(), 5);
    assert!(
        (sub.robot.gravity - full_gravity()).norm() > 1.0,
        "gravity turned"
    );
    assert!(
        sub.folded
            .iter()
            .any(|f| f.name == "panda_joint1" && f.carried_by.is_none())
    );
    let mut full = Robot::load_chain(&case.urdf, &case.selection)
        .unwrap()
        .robot;
    full.lock_joint(0, q1);
    full.lock_joint(1, q2);
    let (q, qd, qdd) = ([-0.2, 0.1, -1.5, 0.4, 1.0], [0.5; 5], [-1.0; 5]);
    let a = rnea(
        &sub.robot,
        &sub.robot.standard_parameters(),
        &q,
        &qd,
        &qdd,
        &sub.robot.gravity,
    );
    let b = rnea(
        &full,
        &full.standard_parameters(),
        &q,
        &qd,
        &qdd,
        &full.gravity,
    );
    assert!((&a - &b).norm() <= 1e-12 * b.norm(), "{a} vs {b}");
}

fn full_gravity() -> nalgebra::Vector3<f64> {
    nalgebra::Vector3::new(0.0, 0.0, -9.81)
}

fn joint(name: &str, kind: &str, parent: &str, child: &str) -> String {
    format!(
        "  <joint name=\"{name}\" type=\"{kind}\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    <axis xyz=\"0 0 1\"/>\n    <limit lower=\"-1\" upper=\"1\" effort=\"10\" velocity=\"2\"/>\n  </joint>\n"
    )
}

fn link(name: &str) -> String {
    format!(
        "  <link name=\"{name}\"><inertial><mass value=\"1\"/><inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/></inertial></link>\n"
    )
}

#[test]
fn a_64_joint_chain_parses_and_a_4000_joint_chain_is_refused() {
    let text = chain_urdf(artifacts::plausible::MAX_JOINTS);
    let r = Robot::from_urdf_str(&text, "long.urdf").unwrap();
    assert_eq!(r.dof(), artifacts::plausible::MAX_JOINTS);
    assert_eq!(r.joints[63].name, "j63");
    // A modelled chain longer than any arm: refused by name before anything is sized
    // by it.
    let text = chain_urdf(4000);
    let e = Robot::from_urdf_str(&text, "long.urdf").unwrap_err();
    assert!(
        e.to_string().contains("long.urdf") && e.to_string().contains("MAX_JOINTS"),
        "{e}"
    );
    // Over the limit: refused by the scan, naming the limit.
    let text = chain_urdf(MAX_URDF_JOINTS + 1);
    let e = Robot::from_urdf_str(&text, "huge.urdf").unwrap_err();
    assert!(
        e.to_string().contains("huge.urdf") && e.message.contains("(the limit, MAX_URDF_"),
        "{e}"
    );
}

#[test]
fn joints_that_loop_under_a_real_root_are_refused_by_name() {
    // base -> a -> b -> c, and c -> a closes a loop below a real root.
    let mut t = String::from("<robot name=\"r\">\n");
    for l in ["base", "a", "b", "c"] {
        t.push_str(&link(l));
    }
    t.push_str(&joint("j1", "revolute", "base", "a"));
    t.push_str(&joint("j2", "revolute", "a", "b"));
    t.push_str(&joint("j3", "revolute", "b", "c"));
    t.push_str(&joint("back", "revolute", "c", "a"));
    t.push_str("</robot>\n");
    let e = Robot::from_urdf_str(&t, "loop.urdf").unwrap_err();
    assert!(
        e.field.contains("\"back\"") && e.message.contains("\"j1\"") && e.line.is_some(),
        "{e}"
    );
    // A loop that hangs nowhere (its links are nobody's root) beside a good chain.
    let mut t = String::from("<robot name=\"r\">\n");
    for l in ["base", "a", "x", "y"] {
        t.push_str(&link(l));
    }
    t.push_str(&joint("j1", "revolute", "base", "a"));
    t.push_str(&joint("xy", "revolute", "x", "y"));
    t.push_str(&joint("yx", "revolute", "y", "x"));
    t.push_str("</robot>\n");
    let e = Robot::from_urdf_str(&t, "island.urdf").unwrap_err();
    assert!(
        e.message.contains("loop") && e.message.contains("\"xy\"") && e.message.contains("\"yx\""),
        "{e}"
    );
    // A joint whose parent is its child.
    let t = format!(
        "<robot name=\"r\">\n{}{}{}</robot>\n",
        link("base"),
        link("a"),
        joint("self", "revolute", "a", "a")
    );
    let e = Robot::from_urdf_str(&t, "self.urdf").unwrap_err();
    assert!(
        e.field.contains("\"self\"") && e.message.contains("loop"),
        "{e}"
    );
    // Several roots.
    let t = format!(
        "<robot name=\"r\">\n{}{}{}{}</robot>\n",
        link("base"),
        link("a"),
        link("stray"),
        joint("j1", "revolute", "base", "a")
    );
    let e = Robot::from_urdf_str(&t, "roots.urdf").unwrap_err();
    assert!(
        e.message.contains("2 root links") && e.message.contains("\"stray\""),
        "{e}"
    );
}

#[test]
fn doubled_fixed_joints_are_refused_not_expanded() {
    // 60 levels, each link joined to the next by two fixed joints: the old reader walked
    // every path (2^60). A link has one parent: the second joint is named.
    let mut t = String::from("<robot name=\"r\">\n");
    t.push_str(&link("base"));
    t.push_str(&link("l0"));
    t.push_str(&joint("j", "revolute", "base", "l0"));
    for i in 0..60 {
        t.push_str(&link(&format!("l{}", i + 1)));
        t.push_str(&joint(
            &format!("f{i}a"),
            "fixed",
            &format!("l{i}"),
            &format!("l{}", i + 1),
        ));
        t.push_str(&joint(
            &format!("f{i}b"),
            "fixed",
            &format!("l{i}"),
            &format!("l{}", i + 1),
        ));
    }
    t.push_str("</robot>\n");
    let e = Robot::from_urdf_str(&t, "doubled.urdf").unwrap_err();
    assert!(
        e.field.contains("\"f0b\"") && e.message.contains("\"f0a\"") && e.line.is_some(),
        "{e}"
    );
    // A legal binary tree of fixed joints (every link two children; 2^12 - 1 links) on
    // one moving joint is merged into one body: every link counted once.
    let mut t = String::from("<robot name=\"r\">\n");
    t.push_str(&link("base"));
    t.push_str(&link("t1"));
    t.push_str(&joint("j", "revolute", "base", "t1"));
    for i in 2..(1usize << 12) {
        t.push_str(&link(&format!("t{i}")));
        t.push_str(&joint(
            &format!("f{i}"),
            "fixed",
            &format!("t{}", i / 2),
            &format!("t{i}"),
        ));
    }
    t.push_str("</robot>\n");
    let r = Robot::from_urdf_str(&t, "tree.urdf").unwrap();
    assert_eq!(r.dof(), 1);
    assert_eq!(r.joints[0].inertial.mass_kg, ((1usize << 12) - 1) as f64);
}

/// Equal (or crossed) joint limits are refused alike in a URDF and in a DH table, by the
/// same plausibility check, naming the file, the line and the field.
#[test]
fn equal_limits_are_refused_in_urdf_and_dh_toml_alike() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/dh_toml");
    let toml = std::fs::read_to_string(dir.join("limits_equal.toml")).unwrap();
    let e =
        Robot::parse_chain(&toml, Path::new("equal.toml"), &ChainSelection::default()).unwrap_err();
    assert!(e.line.is_some() && e.field.contains("q_max"), "{e}");
    assert!(e.message.contains("ordered and distinct"), "{e}");
    let urdf = std::fs::read_to_string(fixture_dir().join("mimic_gripper.urdf")).unwrap();
    let urdf = urdf.replacen(
        "<limit lower=\"-2.8\" upper=\"2.8\"",
        "<limit lower=\"0.5\" upper=\"0.5\"",
        1,
    );
    let tip = ChainSelection {
        tip_link: Some("l3".into()),
        ..ChainSelection::default()
    };
    let e = Robot::parse_chain(&urdf, Path::new("equal.urdf"), &tip).unwrap_err();
    assert!(e.line.is_some() && e.field.contains("limit"), "{e}");
    assert!(e.message.contains("ordered and distinct"), "{e}");
}
