//! URDF reader (urdf-rs): a serial chain of revolute/continuous joints; fixed joints
//! are merged into their parent body; links before the first revolute joint are the
//! base (their inertia is not modelled).
use super::*;

/// Line of the first `<tag ... name="name"` in `text`.
fn element_line(text: &str, tag: &str, name: &str) -> Option<usize> {
    let open = format!("<{tag}");
    let mut search = 0;
    while let Some(off) = text[search..].find(&open) {
        let start = search + off;
        let end = text[start..]
            .find('>')
            .map(|e| start + e)
            .unwrap_or(text.len());
        let head = &text[start..end];
        if head.contains(&format!("name=\"{name}\"")) || head.contains(&format!("name='{name}'")) {
            return Some(dh::line_of(text, start));
        }
        search = start + open.len();
    }
    None
}

/// Minimal well-formedness scan with line numbers (urdf-rs reports XML errors
/// without positions): mismatched or unclosed tags.
fn check_tags(text: &str) -> Result<(), (usize, String, String)> {
    let mut stack: Vec<(String, usize)> = Vec::new();
    let bytes = text.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] != b'<' {
            i += 1;
            continue;
        }
        let line = dh::line_of(text, i);
        let rest = &text[i..];
        if rest.starts_with("<!--") {
            match rest.find("-->") {
                Some(e) => i += e + 3,
                None => return Err((line, "<comment>".into(), "unterminated comment".into())),
            }
            continue;
        }
        if rest.starts_with("<?") || rest.starts_with("<!") {
            match rest.find('>') {
                Some(e) => i += e + 1,
                None => {
                    return Err((
                        line,
                        "<declaration>".into(),
                        "unterminated declaration".into(),
                    ));
                }
            }
            continue;
        }
        let Some(end) = rest.find('>') else {
            return Err((line, "<tag>".into(), "unterminated tag".into()));
        };
        let inner = &rest[1..end];
        if let Some(name) = inner.strip_prefix('/') {
            let name = name.trim().to_string();
            match stack.pop() {
                Some((open, _)) if open == name => {}
                Some((open, oline)) => {
                    return Err((
                        oline,
                        open.clone(),
                        format!("<{open}> is not closed: </{name}> on line {line} comes first"),
                    ));
                }
                None => {
                    return Err((
                        line,
                        name.clone(),
                        format!("closing </{name}> without opening tag"),
                    ));
                }
            }
        } else {
            let name = inner
                .split_whitespace()
                .next()
                .unwrap_or("")
                .trim_end_matches('/')
                .to_string();
            check_numbers(&name, inner).map_err(|(field, msg)| (line, field, msg))?;
            if !inner.ends_with('/') {
                stack.push((name, line));
            }
        }
        i += end + 1;
    }
    if let Some((open, line)) = stack.pop() {
        return Err((line, open.clone(), format!("<{open}> is never closed")));
    }
    Ok(())
}

/// Numeric attributes of the URDF elements this reader uses.
const NUMERIC_ATTRIBUTES: [&str; 14] = [
    "xyz", "rpy", "value", "ixx", "ixy", "ixz", "iyy", "iyz", "izz", "lower", "upper", "effort",
    "velocity", "damping",
];

/// Checks that the numeric attributes of one tag (`inner`: the text between `<` and
/// `>`) parse as numbers; returns (field, message) otherwise.
fn check_numbers(tag: &str, inner: &str) -> Result<(), (String, String)> {
    for attr in NUMERIC_ATTRIBUTES {
        for quote in ['"', '\''] {
            let key = format!(" {attr}={quote}");
            let mut from = 0;
            while let Some(off) = inner[from..].find(&key) {
                let start = from + off + key.len();
                let Some(len) = inner[start..].find(quote) else {
                    break;
                };
                let value = &inner[start..start + len];
                for word in value.split_whitespace() {
                    if word.parse::<f64>().is_err() {
                        return Err((
                            format!("<{tag}> {attr}"),
                            format!("`{word}` is not a number"),
                        ));
                    }
                }
                from = start + len;
            }
        }
    }
    Ok(())
}

fn pose(p: &urdf_rs::Pose) -> (Matrix3<f64>, Vector3<f64>) {
    (rpy_rotation(p.rpy.0), Vector3::from(p.xyz.0))
}

/// Standard parameters of a URDF link in its own frame.
fn link_parameters(l: &urdf_rs::Link) -> [f64; 10] {
    let (r, c) = pose(&l.inertial.origin);
    let i = &l.inertial.inertia;
    let ic = inertia_matrix(&[i.ixx, i.iyy, i.izz, i.ixy, i.ixz, i.iyz]);
    LinkInertial {
        mass_kg: l.inertial.mass.value,
        com_m: c,
        inertia_com: r * ic * r.transpose(),
    }
    .standard_parameters()
}

/// Whether the subtree below joint `j` contains a moving joint.
fn moves(model: &urdf_rs::Robot, j: &urdf_rs::Joint, depth: usize) -> bool {
    if j.joint_type != urdf_rs::JointType::Fixed {
        return true;
    }
    depth <= model.joints.len()
        && model
            .joints
            .iter()
            .filter(|c| c.parent.link == j.child.link)
            .any(|c| moves(model, c, depth + 1))
}

/// Adds the parameters of the rigid subtree below fixed joint `j` (placed at `(r, p)` in
/// the body frame) to `acc`.
fn merge_rigid(
    model: &urdf_rs::Robot,
    j: &urdf_rs::Joint,
    r: &Matrix3<f64>,
    p: &Vector3<f64>,
    acc: &mut [f64; 10],
    depth: usize,
) {
    if depth > model.joints.len() {
        return;
    }
    if let Some(l) = model.links.iter().find(|l| l.name == j.child.link) {
        let t = transform_standard_parameters(&link_parameters(l), r, p);
        for k in 0..10 {
            acc[k] += t[k];
        }
    }
    for c in model
        .joints
        .iter()
        .filter(|c| c.parent.link == j.child.link)
    {
        let (r0, p0) = pose(&c.origin);
        merge_rigid(model, c, &(r * r0), &(r * p0 + p), acc, depth + 1);
    }
}

pub(super) fn parse(text: &str, file: &Path) -> Result<Robot, RobotError> {
    let err = |line: Option<usize>, field: String, message: String| RobotError {
        file: file.to_path_buf(),
        line,
        field,
        message,
    };
    check_tags(text).map_err(|(line, field, msg)| err(Some(line), field, msg))?;
    let model = urdf_rs::read_from_string(text).map_err(|e| {
        let msg = e.to_string();
        // Locate the first quoted or back-quoted name of the message in the text.
        let token = msg.split(['`', '"']).nth(1).map(str::to_string);
        let line = token.as_ref().and_then(|t| {
            text.find(&format!("<{t}"))
                .or_else(|| text.find(&format!("{t}=")))
                .map(|p| dh::line_of(text, p))
        });
        err(line, token.unwrap_or_else(|| "<urdf>".into()), msg)
    })?;
    let link_err = |name: &str, field: &str, message: String| {
        err(
            element_line(text, "link", name),
            format!("link \"{name}\" {field}"),
            message,
        )
    };
    let joint_err = |name: &str, field: &str, message: String| {
        err(
            element_line(text, "joint", name),
            format!("joint \"{name}\" {field}"),
            message,
        )
    };
    // Validate links.
    for l in &model.links {
        let i = &l.inertial.inertia;
        let vals = [
            l.inertial.mass.value,
            i.ixx,
            i.iyy,
            i.izz,
            i.ixy,
            i.ixz,
            i.iyz,
        ];
        if vals.iter().any(|v| !v.is_finite())
            || l.inertial.origin.xyz.0.iter().any(|v| !v.is_finite())
        {
            return Err(link_err(&l.name, "inertial", "non-finite number".into()));
        }
        if l.inertial.mass.value < 0.0 {
            return Err(link_err(
                &l.name,
                "inertial.mass",
                format!("negative mass {}", l.inertial.mass.value),
            ));
        }
        let ic = inertia_matrix(&[i.ixx, i.iyy, i.izz, i.ixy, i.ixz, i.iyz]);
        let eig = ic.symmetric_eigenvalues();
        if eig.iter().any(|&e| e < -1e-9 * eig.amax().max(1e-12)) {
            return Err(link_err(
                &l.name,
                "inertial.inertia",
                "not positive semi-definite".into(),
            ));
        }
    }
    // Root: the link that is no joint's child.
    let is_child = |name: &str| model.joints.iter().any(|j| j.child.link == name);
    let roots: Vec<&str> = model
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|n| !is_child(n))
        .collect();
    let root = match roots.as_slice() {
        [r] => *r,
        [] => {
            return Err(err(
                None,
                "link".into(),
                "no root link (the joints form a loop)".into(),
            ));
        }
        many => {
            return Err(err(
                None,
                "link".into(),
                format!("several root links: {many:?}"),
            ));
        }
    };
    let link_by_name = |n: &str| model.links.iter().find(|l| l.name == n);
    let mut joints: Vec<Joint> = Vec::new();
    // Pending fixed transform from the current body frame (or base) to the current link.
    let mut acc: (Matrix3<f64>, Vector3<f64>) = (Matrix3::identity(), Vector3::zeros());
    let mut body_params: Option<[f64; 10]> = None;
    let mut current = root.to_string();
    loop {
        let children: Vec<&urdf_rs::Joint> = model
            .joints
            .iter()
            .filter(|j| j.parent.link == current)
            .collect();
        let (moving, rigid): (Vec<&urdf_rs::Joint>, Vec<&urdf_rs::Joint>) =
            children.into_iter().partition(|j| moves(&model, j, 0));
        // Branches of fixed joints only are rigid attachments of the current body.
        for j in rigid {
            let (r0, p0) = pose(&j.origin);
            let (ar, ap) = acc;
            if let Some(b) = body_params.as_mut() {
                merge_rigid(&model, j, &(ar * r0), &(ar * p0 + ap), b, 0);
            }
        }
        let j = match moving.as_slice() {
            [] => break,
            [j] => *j,
            many => {
                return Err(link_err(
                    &current,
                    "children",
                    format!(
                        "not a serial chain: {} moving branches leave this link",
                        many.len()
                    ),
                ));
            }
        };
        let child = link_by_name(&j.child.link).ok_or_else(|| {
            joint_err(
                &j.name,
                "child",
                format!("unknown link \"{}\"", j.child.link),
            )
        })?;
        let (r0, p0) = pose(&j.origin);
        if r0.iter().chain(p0.iter()).any(|v| !v.is_finite()) {
            return Err(joint_err(&j.name, "origin", "non-finite number".into()));
        }
        // X in the current body frame.
        let (ar, ap) = acc;
        let (xr, xp) = (ar * r0, ar * p0 + ap);
        let params = link_parameters(child);
        match &j.joint_type {
            urdf_rs::JointType::Fixed => {
                acc = (xr, xp);
                if let Some(b) = body_params.as_mut() {
                    let t = transform_standard_parameters(&params, &xr, &xp);
                    for k in 0..10 {
                        b[k] += t[k];
                    }
                }
            }
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                let a = Vector3::from(j.axis.xyz.0);
                if !a.iter().all(|v| v.is_finite()) || a.norm() < 1e-9 {
                    return Err(joint_err(
                        &j.name,
                        "axis",
                        format!("invalid axis {:?}", j.axis.xyz.0),
                    ));
                }
                if let (Some(b), Some(prev)) = (body_params.take(), joints.last_mut()) {
                    prev.inertial = LinkInertial::from_standard_parameters(&b);
                }
                let lim = &j.limit;
                let revolute = j.joint_type == urdf_rs::JointType::Revolute;
                let some_pos = |v: f64| (v.is_finite() && v > 0.0).then_some(v);
                let limits = JointLimits {
                    q_min_rad: (revolute && lim.lower.is_finite()).then_some(lim.lower),
                    q_max_rad: (revolute && lim.upper.is_finite()).then_some(lim.upper),
                    qd_max_rad_s: some_pos(lim.velocity),
                    qdd_max_rad_s2: some_pos(lim.acceleration),
                    effort_max_nm: some_pos(lim.effort),
                };
                if let (Some(lo), Some(hi)) = (limits.q_min_rad, limits.q_max_rad) {
                    if lo > hi {
                        return Err(joint_err(
                            &j.name,
                            "limit",
                            format!("lower {lo} > upper {hi}"),
                        ));
                    }
                }
                let friction = j
                    .dynamics
                    .as_ref()
                    .map(|d| JointFriction {
                        viscous_nm_s_rad: d.damping,
                        coulomb_nm: d.friction,
                        offset_nm: 0.0,
                    })
                    .unwrap_or_default();
                joints.push(Joint {
                    name: j.name.clone(),
                    origin_rotation: xr,
                    origin_translation: xp,
                    axis: Unit::new_normalize(a),
                    link_frame: None,
                    inertial: LinkInertial::zero(),
                    limits,
                    drive: JointDrive::default(),
                    friction,
                    mode: JointMode::Modelled,
                });
                acc = (Matrix3::identity(), Vector3::zeros());
                body_params = Some(params);
            }
            other => {
                return Err(joint_err(
                    &j.name,
                    "type",
                    format!("unsupported joint type {other:?} (revolute, continuous, fixed)"),
                ));
            }
        }
        current = child.name.clone();
    }
    if let (Some(b), Some(prev)) = (body_params.take(), joints.last_mut()) {
        prev.inertial = LinkInertial::from_standard_parameters(&b);
    }
    if joints.is_empty() {
        return Err(err(
            None,
            "joint".into(),
            "no revolute joint in the chain".into(),
        ));
    }
    Ok(Robot {
        name: model.name.clone(),
        source: file.to_path_buf(),
        gravity: Vector3::new(0.0, 0.0, -9.81),
        joints,
        terms: ModelTerms::default(),
    })
}
