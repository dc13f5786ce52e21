//! URDF reader. One pass of quick-xml checks well-formedness, numbers, nesting and size
//! limits and records the line of every link and joint (for errors); urdf-rs reads the
//! elements; the kinematic tree is then built with name maps in linear time, and checked:
//! every link has at most one parent joint, there is exactly one root and every link is
//! reached from it (no loops). One chain, base link to tip link ([`ChainSelection`]), is
//! modelled: its revolute and continuous joints are the robot's joints, fixed joints on it
//! are merged into their parent body, and every branch off it rides on the chain link it
//! hangs from as a fixed body (moving joints in it held at a position, reported as
//! [`FoldedJoint`]s). Links from the base link to the first moving joint of the chain are
//! the base (their inertia is not modelled).
use super::*;
use quick_xml::events::Event;
use std::collections::HashMap;

/// Deepest element nesting accepted in a URDF.
pub const MAX_URDF_DEPTH: usize = 32;

/// Names listed at most in one error message.
const LISTED_NAMES: usize = 12;

/// Line of each top-level `<link>` and `<joint>` element, by name.
#[derive(Default)]
struct Positions {
    links: HashMap<String, usize>,
    joints: HashMap<String, usize>,
    /// Bytes the line counter read (the text's length at most: each byte once).
    line_bytes_read: usize,
}

/// Line numbers of increasing byte positions, counted once over the text.
struct LineCounter<'a> {
    text: &'a [u8],
    pos: usize,
    line: usize,
    bytes_read: usize,
}

impl LineCounter<'_> {
    fn line_at(&mut self, pos: usize) -> usize {
        let pos = pos.min(self.text.len());
        if pos < self.pos {
            self.pos = 0;
            self.line = 1;
        }
        self.bytes_read += pos - self.pos;
        self.line += self.text[self.pos..pos]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        self.pos = pos;
        self.line
    }
}

/// (line, field, message) of a scan error.
type ScanError = (usize, String, String);

/// Numeric attributes of the URDF elements this reader uses.
const NUMERIC_ATTRIBUTES: [&str; 16] = [
    "xyz",
    "rpy",
    "value",
    "ixx",
    "ixy",
    "ixz",
    "iyy",
    "iyz",
    "izz",
    "lower",
    "upper",
    "effort",
    "velocity",
    "damping",
    "friction",
    "multiplier",
];

/// One linear pass over the XML: well-formed, every numeric attribute a number, sizes
/// within [`MAX_URDF_LINKS`], [`MAX_URDF_JOINTS`], [`MAX_URDF_ATTRIBUTES`] and
/// [`MAX_URDF_DEPTH`]; returns where the links and joints are.
fn scan(text: &str) -> Result<Positions, ScanError> {
    let mut reader = quick_xml::Reader::from_str(text);
    // End names are checked here, to report both lines.
    reader.config_mut().check_end_names = false;
    let mut lines = LineCounter {
        text: text.as_bytes(),
        pos: 0,
        line: 1,
        bytes_read: 0,
    };
    let mut stack: Vec<(String, usize)> = Vec::new();
    let mut positions = Positions::default();
    let (mut n_links, mut n_joints) = (0usize, 0usize);
    loop {
        let at = reader.buffer_position() as usize;
        let event = match reader.read_event() {
            Ok(e) => e,
            Err(e) => {
                let line = lines.line_at(reader.error_position() as usize);
                return Err((line, "<xml>".into(), format!("malformed XML: {e}")));
            }
        };
        match &event {
            Event::Start(e) | Event::Empty(e) => {
                let line = lines.line_at(at);
                let tag = String::from_utf8_lossy(e.name().as_ref()).into_owned();
                let mut element_name = None;
                for (count, a) in e.attributes().with_checks(false).enumerate() {
                    let a = a.map_err(|err| {
                        (
                            line,
                            format!("<{tag}>"),
                            format!("malformed attribute: {err}"),
                        )
                    })?;
                    if count >= MAX_URDF_ATTRIBUTES {
                        return Err((
                            line,
                            format!("<{tag}>"),
                            format!(
                                "more than {MAX_URDF_ATTRIBUTES} attributes (the limit, MAX_URDF_ATTRIBUTES)"
                            ),
                        ));
                    }
                    let key = a.key.as_ref();
                    let Ok(value) = std::str::from_utf8(&a.value) else {
                        return Err((line, format!("<{tag}>"), "attribute is not UTF-8".into()));
                    };
                    if key == b"name" {
                        element_name = Some(value.to_string());
                    }
                    if let Some(attr) = NUMERIC_ATTRIBUTES.iter().find(|n| n.as_bytes() == key) {
                        for word in value.split_whitespace() {
                            if word.parse::<f64>().is_err() {
                                return Err((
                                    line,
                                    format!("<{tag}> {attr}"),
                                    format!("`{word}` is not a number"),
                                ));
                            }
                        }
                    }
                }
                if stack.len() == 1 {
                    let (count, limit, limit_name, map) = match tag.as_str() {
                        "link" => (
                            &mut n_links,
                            MAX_URDF_LINKS,
                            "MAX_URDF_LINKS",
                            &mut positions.links,
                        ),
                        "joint" => (
                            &mut n_joints,
                            MAX_URDF_JOINTS,
                            "MAX_URDF_JOINTS",
                            &mut positions.joints,
                        ),
                        _ => {
                            if matches!(event, Event::Start(_)) {
                                stack.push((tag, line));
                            }
                            continue;
                        }
                    };
                    *count += 1;
                    if *count > limit {
                        return Err((
                            line,
                            format!("<{tag}>"),
                            format!("more than {limit} <{tag}> elements (the limit, {limit_name})"),
                        ));
                    }
                    if let Some(n) = element_name {
                        map.entry(n).or_insert(line);
                    }
                }
                if matches!(event, Event::Start(_)) {
                    if stack.len() >= MAX_URDF_DEPTH {
                        return Err((
                            line,
                            format!("<{tag}>"),
                            format!(
                                "elements nested deeper than {MAX_URDF_DEPTH} (the limit, MAX_URDF_DEPTH)"
                            ),
                        ));
                    }
                    stack.push((tag, line));
                }
            }
            Event::End(e) => {
                let line = lines.line_at(at);
                let tag = String::from_utf8_lossy(e.name().as_ref()).into_owned();
                match stack.pop() {
                    Some((open, _)) if open == tag => {}
                    Some((open, open_line)) => {
                        return Err((
                            open_line,
                            open.clone(),
                            format!("<{open}> is not closed: </{tag}> on line {line} comes first"),
                        ));
                    }
                    None => {
                        return Err((
                            line,
                            tag.clone(),
                            format!("closing </{tag}> without opening tag"),
                        ));
                    }
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if let Some((open, line)) = stack.pop() {
        return Err((line, open.clone(), format!("<{open}> is never closed")));
    }
    positions.line_bytes_read = lines.bytes_read;
    Ok(positions)
}

/// At most [`LISTED_NAMES`] names, quoted, then how many more.
fn list_names<'a>(names: impl ExactSizeIterator<Item = &'a str>) -> String {
    let total = names.len();
    let mut s: Vec<String> = names
        .take(LISTED_NAMES)
        .map(|n| format!("\"{n}\""))
        .collect();
    if total > LISTED_NAMES {
        s.push(format!("and {} more", total - LISTED_NAMES));
    }
    s.join(", ")
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

fn is_moving(j: &urdf_rs::Joint) -> bool {
    j.joint_type != urdf_rs::JointType::Fixed
}

fn type_name(t: &urdf_rs::JointType) -> String {
    format!("{t:?}").to_ascii_lowercase()
}

/// Adds `params`, given in a frame placed at `(r, p)` in the body frame, to `body`.
fn add_params(body: &mut [f64; 10], params: &[f64; 10], r: &Matrix3<f64>, p: &Vector3<f64>) {
    let t = transform_standard_parameters(params, r, p);
    for (b, v) in body.iter_mut().zip(t) {
        *b += v;
    }
}

pub(super) fn parse(
    text: &str,
    file: &Path,
    selection: &ChainSelection,
) -> Result<LoadedRobot, RobotError> {
    let err = |line: Option<usize>, field: String, message: String| RobotError {
        file: file.to_path_buf(),
        line,
        field,
        message,
    };
    if text.len() > MAX_URDF_BYTES {
        return Err(err(
            None,
            "<file>".into(),
            format!(
                "{} bytes: larger than the limit of {MAX_URDF_BYTES} bytes (MAX_URDF_BYTES)",
                text.len()
            ),
        ));
    }
    let positions = scan(text).map_err(|(line, field, msg)| err(Some(line), field, msg))?;
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
            positions.links.get(name).copied(),
            format!("link \"{name}\" {field}"),
            message,
        )
    };
    let joint_err = |name: &str, field: &str, message: String| {
        err(
            positions.joints.get(name).copied(),
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
            || l.inertial.origin.rpy.0.iter().any(|v| !v.is_finite())
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
        let rows = [
            [ic[(0, 0)], ic[(0, 1)], ic[(0, 2)]],
            [ic[(1, 0)], ic[(1, 1)], ic[(1, 2)]],
            [ic[(2, 0)], ic[(2, 1)], ic[(2, 2)]],
        ];
        artifacts::plausible::rigid_body(l.inertial.mass.value, &rows)
            .map_err(|m| link_err(&l.name, "inertial.inertia", m))?;
    }
    // The tree: name maps, one parent per link, one root, every link reached.
    let n = model.links.len();
    let mut link_index: HashMap<&str, usize> = HashMap::with_capacity(n);
    for (i, l) in model.links.iter().enumerate() {
        if link_index.insert(l.name.as_str(), i).is_some() {
            return Err(link_err(&l.name, "name", "defined twice".into()));
        }
    }
    let mut joint_index: HashMap<&str, usize> = HashMap::with_capacity(model.joints.len());
    for (i, j) in model.joints.iter().enumerate() {
        if joint_index.insert(j.name.as_str(), i).is_some() {
            return Err(joint_err(&j.name, "name", "defined twice".into()));
        }
    }
    let mut parent_joint: Vec<Option<usize>> = vec![None; n];
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
    // (parent link, child link) of every joint.
    let mut ends: Vec<(usize, usize)> = Vec::with_capacity(model.joints.len());
    for (ji, j) in model.joints.iter().enumerate() {
        let p = *link_index.get(j.parent.link.as_str()).ok_or_else(|| {
            joint_err(
                &j.name,
                "parent",
                format!("unknown link \"{}\"", j.parent.link),
            )
        })?;
        let c = *link_index.get(j.child.link.as_str()).ok_or_else(|| {
            joint_err(
                &j.name,
                "child",
                format!("unknown link \"{}\"", j.child.link),
            )
        })?;
        if p == c {
            return Err(joint_err(
                &j.name,
                "child",
                format!(
                    "link \"{}\" is its own parent: the joints form a loop",
                    j.child.link
                ),
            ));
        }
        if let Some(other) = parent_joint[c] {
            return Err(joint_err(
                &j.name,
                "child",
                format!(
                    "link \"{}\" already has the parent joint \"{}\": a link has one parent (the joints form a loop or a doubled joint)",
                    j.child.link, model.joints[other].name
                ),
            ));
        }
        parent_joint[c] = Some(ji);
        children[p].push(ji);
        ends.push((p, c));
    }
    // The joints of the loop that link `start` (not reached from the root) hangs in.
    let loop_error = |start: usize| {
        // Every link not reached from the root has a parent; n steps up lead into the loop.
        let mut l = start;
        for _ in 0..n {
            l = parent_joint[l].map_or(l, |ji| ends[ji].0);
        }
        let first = l;
        let mut names = Vec::new();
        while let Some(ji) = parent_joint[l] {
            names.push(model.joints[ji].name.as_str());
            l = ends[ji].0;
            if l == first || names.len() > n {
                break;
            }
        }
        names.reverse();
        let field_joint = names.first().copied().unwrap_or("");
        joint_err(
            field_joint,
            "parent",
            format!(
                "the joints {} form a loop (link \"{}\" is not reached from the root)",
                list_names(names.iter().copied()),
                model.links[start].name
            ),
        )
    };
    let roots: Vec<usize> = (0..n).filter(|&i| parent_joint[i].is_none()).collect();
    let root = match roots.as_slice() {
        [r] => *r,
        [] if n == 0 => return Err(err(None, "link".into(), "no links".into())),
        [] => return Err(loop_error(0)),
        many => {
            return Err(err(
                None,
                "link".into(),
                format!(
                    "{} root links (links that are no joint's child) where a tree has one: {}",
                    many.len(),
                    list_names(many.iter().map(|&i| model.links[i].name.as_str()))
                ),
            ));
        }
    };
    // Depth-first order from the root (iterative: no recursion on hostile depth).
    let mut order: Vec<usize> = Vec::with_capacity(n);
    let mut reached = vec![false; n];
    let mut stack = vec![root];
    while let Some(l) = stack.pop() {
        reached[l] = true;
        order.push(l);
        stack.extend(children[l].iter().rev().map(|&ji| ends[ji].1));
    }
    if let Some(u) = (0..n).find(|&i| !reached[i]) {
        return Err(loop_error(u));
    }
    // Whether a moving joint lies below each link (children come after parents in `order`).
    let mut moving_below = vec![false; n];
    for &l in order.iter().rev() {
        if let Some(ji) = parent_joint[l] {
            let below = moving_below[l] || is_moving(&model.joints[ji]);
            moving_below[ends[ji].0] |= below;
        }
    }
    let link_named = |name: &str, what: &str| {
        link_index.get(name).copied().ok_or_else(|| {
            err(
                None,
                what.to_string(),
                format!("no link \"{name}\" in the robot"),
            )
        })
    };
    let base = match &selection.base_link {
        Some(b) => link_named(b, "base link")?,
        None => root,
    };
    let tip = match &selection.tip_link {
        Some(t) => link_named(t, "tip link")?,
        None => {
            // Links below the base that end a path of moving joints.
            let mut below_base = vec![false; n];
            below_base[base] = true;
            let mut candidates = Vec::new();
            for &l in &order {
                let Some(ji) = parent_joint[l] else { continue };
                if !below_base[ends[ji].0] {
                    continue;
                }
                below_base[l] = true;
                if is_moving(&model.joints[ji]) && !moving_below[l] {
                    candidates.push(l);
                }
            }
            match candidates.as_slice() {
                [t] => *t,
                [] => {
                    return Err(err(
                        None,
                        "tip link".into(),
                        format!(
                            "no moving joint below the base link \"{}\"",
                            model.links[base].name
                        ),
                    ));
                }
                many => {
                    return Err(err(
                        None,
                        "tip link".into(),
                        format!(
                            "the tree below \"{}\" has {} branches of moving joints; choose the chain's tip with --tip-link, one of: {}",
                            model.links[base].name,
                            many.len(),
                            list_names(many.iter().map(|&i| model.links[i].name.as_str()))
                        ),
                    ));
                }
            }
        }
    };
    // The chain: joints from the base link to the tip link.
    let mut chain: Vec<usize> = Vec::new();
    let mut l = tip;
    while l != base {
        let Some(ji) = parent_joint[l] else {
            return Err(err(
                None,
                "tip link".into(),
                format!(
                    "link \"{}\" is not below the base link \"{}\"",
                    model.links[tip].name, model.links[base].name
                ),
            ));
        };
        chain.push(ji);
        l = ends[ji].0;
    }
    chain.reverse();
    let mut on_chain = vec![false; model.joints.len()];
    for &ji in &chain {
        on_chain[ji] = true;
    }
    // Positions of the joints outside the chain.
    let mut side: HashMap<&str, (f64, bool)> = HashMap::new();
    for (name, q) in &selection.side_joint_positions {
        let side_err = |m: String| err(None, format!("side joint \"{name}\""), m);
        let Some(&ji) = joint_index.get(name.as_str()) else {
            return Err(side_err("no joint of this name".into()));
        };
        let j = &model.joints[ji];
        if on_chain[ji] {
            return Err(side_err(
                "is a joint of the chain (a chain joint is held with --lock)".into(),
            ));
        }
        if !is_moving(j) {
            return Err(side_err("is a fixed joint".into()));
        }
        if !q.is_finite() {
            return Err(side_err(format!("position {q} is not finite")));
        }
        let (lo, hi) = (j.limit.lower, j.limit.upper);
        if j.joint_type != urdf_rs::JointType::Continuous
            && lo.is_finite()
            && hi.is_finite()
            && lo < hi
            && !(lo..=hi).contains(q)
        {
            return Err(side_err(format!(
                "position {q} is outside the joint's limits [{lo}, {hi}]"
            )));
        }
        if side.insert(name.as_str(), (*q, false)).is_some() {
            return Err(side_err("given twice".into()));
        }
    }
    let mut folded: Vec<FoldedJoint> = Vec::new();
    // The fixed transform of joint `ji` at its held position (moving joints are reported).
    let mut held_transform = |ji: usize,
                              carried_by: Option<&str>,
                              folded: &mut Vec<FoldedJoint>|
     -> Result<(Matrix3<f64>, Vector3<f64>), RobotError> {
        let j = &model.joints[ji];
        let (r0, p0) = pose(&j.origin);
        if r0.iter().chain(p0.iter()).any(|v| !v.is_finite()) {
            return Err(joint_err(&j.name, "origin", "non-finite number".into()));
        }
        if !is_moving(j) {
            return Ok((r0, p0));
        }
        let own = side.get_mut(j.name.as_str()).map(|(q, used)| {
            *used = true;
            *q
        });
        let q = match (own, &j.mimic) {
            (Some(q), _) => q,
            // A <mimic> joint not given its own position follows its master:
            // multiplier * q_master + offset.
            (None, Some(m)) => {
                let mimic_err = |msg: String| joint_err(&j.name, "mimic", msg);
                let Some(&mi) = joint_index.get(m.joint.as_str()) else {
                    return Err(mimic_err(format!("no joint \"{}\" to follow", m.joint)));
                };
                let master = &model.joints[mi];
                if mi == ji || master.mimic.is_some() {
                    return Err(mimic_err(format!(
                        "follows joint \"{}\", which follows a joint itself: a <mimic> joint follows an independent joint",
                        m.joint
                    )));
                }
                // (A chain joint of another type refuses the chain itself, below.)
                if on_chain[mi]
                    && matches!(
                        master.joint_type,
                        urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous
                    )
                {
                    return Err(mimic_err(format!(
                        "follows joint \"{}\" of the chain: a branch that moves with the chain is not a fixed body (choose a --tip-link that puts both in the chain or neither)",
                        m.joint
                    )));
                }
                if !is_moving(master) {
                    return Err(mimic_err(format!(
                        "follows joint \"{}\", a fixed joint",
                        m.joint
                    )));
                }
                let (k, o) = (m.multiplier.unwrap_or(1.0), m.offset.unwrap_or(0.0));
                if !k.is_finite() || !o.is_finite() {
                    return Err(mimic_err(format!(
                        "multiplier {k} and offset {o}: not finite"
                    )));
                }
                let q_master = match side.get_mut(master.name.as_str()) {
                    Some((q, used)) => {
                        *used = true;
                        *q
                    }
                    None => 0.0,
                };
                k * q_master + o
            }
            (None, None) => 0.0,
        };
        let a = Vector3::from(j.axis.xyz.0);
        if !a.iter().all(|v| v.is_finite()) || a.norm() < 1e-9 {
            return Err(joint_err(
                &j.name,
                "axis",
                format!("invalid axis {:?}", j.axis.xyz.0),
            ));
        }
        let a = Unit::new_normalize(a);
        let x = match j.joint_type {
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                (r0 * axis_rotation(&a, q), p0)
            }
            urdf_rs::JointType::Prismatic => (r0, p0 + r0 * a.into_inner() * q),
            ref other => {
                return Err(joint_err(
                    &j.name,
                    "type",
                    format!(
                        "{} joint outside the chain: only revolute, continuous, prismatic and fixed joints can be held fixed",
                        type_name(other)
                    ),
                ));
            }
        };
        folded.push(FoldedJoint {
            name: j.name.clone(),
            joint_type: type_name(&j.joint_type),
            position: q,
            carried_by: carried_by.map(str::to_string),
        });
        Ok(x)
    };
    // Gravity in the base link's frame: the links above it stand at their held positions.
    let mut root_to_base = (Matrix3::identity(), Vector3::zeros());
    {
        let mut above = Vec::new();
        let mut l = base;
        while let Some(ji) = parent_joint[l] {
            above.push(ji);
            l = ends[ji].0;
        }
        for &ji in above.iter().rev() {
            let (r, p) = held_transform(ji, None, &mut folded)?;
            let (ar, ap) = root_to_base;
            root_to_base = (ar * r, ar * p + ap);
        }
    }
    let gravity = root_to_base.0.transpose() * Vector3::new(0.0, 0.0, -9.81);
    let mut joints: Vec<Joint> = Vec::new();
    // Transform from the current body frame (or the base) to the current link.
    let mut acc: (Matrix3<f64>, Vector3<f64>) = (Matrix3::identity(), Vector3::zeros());
    let mut body_params: Option<[f64; 10]> = None;
    let mut current = base;
    let mut next = 0;
    loop {
        // Branches off the current link ride on its body as fixed bodies.
        let carrier = body_params.map(|_| model.links[current].name.as_str());
        let mut branch: Vec<(usize, Matrix3<f64>, Vector3<f64>)> = children[current]
            .iter()
            .filter(|&&ji| !on_chain[ji])
            .rev()
            .map(|&ji| (ji, acc.0, acc.1))
            .collect();
        while let Some((ji, r, p)) = branch.pop() {
            let (xr, xp) = held_transform(ji, carrier, &mut folded)?;
            let (tr, tp) = (r * xr, r * xp + p);
            let child = ends[ji].1;
            if let Some(b) = body_params.as_mut() {
                add_params(b, &link_parameters(&model.links[child]), &tr, &tp);
            }
            branch.extend(children[child].iter().rev().map(|&c| (c, tr, tp)));
        }
        let Some(&ji) = chain.get(next) else { break };
        next += 1;
        let j = &model.joints[ji];
        let child = ends[ji].1;
        let (r0, p0) = pose(&j.origin);
        if r0.iter().chain(p0.iter()).any(|v| !v.is_finite()) {
            return Err(joint_err(&j.name, "origin", "non-finite number".into()));
        }
        // X in the current body frame.
        let (ar, ap) = acc;
        let (xr, xp) = (ar * r0, ar * p0 + ap);
        let params = link_parameters(&model.links[child]);
        match &j.joint_type {
            urdf_rs::JointType::Fixed => {
                acc = (xr, xp);
                if let Some(b) = body_params.as_mut() {
                    add_params(b, &params, &xr, &xp);
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
                if let Some(m) = &j.mimic {
                    return Err(joint_err(
                        &j.name,
                        "mimic",
                        format!(
                            "a chain joint that follows joint \"{}\" (<mimic>): the chain's joints move independently; choose a --tip-link that leaves it in a side branch",
                            m.joint
                        ),
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
                    artifacts::plausible::limits(lo, hi)
                        .map_err(|m| joint_err(&j.name, "limit", m))?;
                }
                let friction = j
                    .dynamics
                    .as_ref()
                    .filter(|_| selection.urdf_friction == UrdfFriction::Nominal)
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
                    profile: None,
                });
                acc = (Matrix3::identity(), Vector3::zeros());
                body_params = Some(params);
            }
            other => {
                return Err(joint_err(
                    &j.name,
                    "type",
                    format!(
                        "{} joint in the chain from \"{}\" to \"{}\": the chain's joints are revolute, continuous or fixed (choose another --tip-link to hold it fixed in a side branch)",
                        type_name(other),
                        model.links[base].name,
                        model.links[tip].name
                    ),
                ));
            }
        }
        current = child;
    }
    if let (Some(b), Some(prev)) = (body_params.take(), joints.last_mut()) {
        prev.inertial = LinkInertial::from_standard_parameters(&b);
    }
    if joints.is_empty() {
        return Err(err(
            None,
            "joint".into(),
            format!(
                "no revolute joint in the chain from \"{}\" to \"{}\"",
                model.links[base].name, model.links[tip].name
            ),
        ));
    }
    if let Some((name, _)) = selection
        .side_joint_positions
        .iter()
        .find(|(name, _)| side.get(name.as_str()).is_some_and(|&(_, used)| !used))
    {
        return Err(err(
            None,
            format!("side joint \"{name}\""),
            "not held by this chain: it is neither on a branch off the chain nor above its base"
                .into(),
        ));
    }
    Ok(LoadedRobot {
        robot: Robot {
            name: model.name.clone(),
            source: file.to_path_buf(),
            gravity,
            joints,
            terms: ModelTerms::default(),
            identified_ranges: Vec::new(),
        },
        chain_links: Some((
            model.links[base].name.clone(),
            model.links[tip].name.clone(),
        )),
        folded,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scan_reads_each_byte_once_for_line_numbers() {
        let mut t = String::from("<robot name=\"r\">\n  <link name=\"l0\"/>\n");
        for i in 0..4000 {
            t.push_str(&format!(
                "  <joint name=\"j{i}\" type=\"revolute\">\n    <parent link=\"l{i}\"/>\n    <child link=\"l{}\"/>\n    <axis xyz=\"0 0 1\"/>\n  </joint>\n  <link name=\"l{}\"/>\n",
                i + 1,
                i + 1
            ));
        }
        t.push_str("</robot>\n");
        let p = scan(&t).unwrap();
        assert_eq!(p.joints.len(), 4000);
        assert_eq!(p.links.len(), 4001);
        assert_eq!(p.joints["j3999"], 3 + 6 * 3999);
        assert!(
            p.line_bytes_read <= t.len(),
            "{} of {}",
            p.line_bytes_read,
            t.len()
        );
    }
}
