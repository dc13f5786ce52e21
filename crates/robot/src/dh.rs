//! DH table reader (TOML). Schema: see the crate README ("DH robot files").
use super::*;
use serde::Deserialize;

/// DH convention of a table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DhConvention {
    /// Standard (distal) DH: `T = Rz(theta) Tz(d) Tx(a) Rx(alpha)`; row `i` holds
    /// `a_i, alpha_i, d_i`; link `i`'s inertial data are in DH frame `i` (distal).
    Standard,
    /// Modified (proximal, Craig) DH: `T = Rx(alpha) Tx(a) Rz(theta) Tz(d)`; row `i`
    /// holds `a_{i-1}, alpha_{i-1}, d_i`; link `i`'s inertial data are in frame `i`.
    Modified,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DhFile {
    name: String,
    convention: DhConvention,
    #[serde(default = "default_gravity")]
    gravity: [f64; 3],
    #[serde(default)]
    terms: Option<TermsToml>,
    joint: Vec<JointToml>,
}

fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, -9.81]
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TermsToml {
    viscous_friction: Option<bool>,
    coulomb_friction: Option<bool>,
    friction_offset: Option<bool>,
    coulomb_smoothing: Option<f64>,
    rotor_inertia: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointToml {
    name: String,
    a: f64,
    alpha: f64,
    d: f64,
    #[serde(default)]
    theta_offset: f64,
    mass: f64,
    com: [f64; 3],
    inertia: [f64; 6],
    q_min: Option<f64>,
    q_max: Option<f64>,
    qd_max: Option<f64>,
    qdd_max: Option<f64>,
    effort_max: Option<f64>,
    drive_gain_nm_per_a: Option<f64>,
    gear_ratio: Option<f64>,
    torque_constant_nm_per_a: Option<f64>,
    rotor_inertia: Option<f64>,
    #[serde(default)]
    friction_viscous: f64,
    #[serde(default)]
    friction_coulomb: f64,
    #[serde(default)]
    friction_offset: f64,
    locked_at: Option<f64>,
    profile: Option<ProfileToml>,
}

/// `[joint.profile]`: the joint drive's settings (`firmware::control::JointProfile`),
/// each field optional (default: `JointProfile::BOARD`'s).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileToml {
    pole_pairs: Option<u8>,
    phase_resistance_ohm: Option<f64>,
    phase_inductance_h: Option<f64>,
    flux_linkage_wb: Option<f64>,
    gear_ratio: Option<f64>,
    gear_efficiency: Option<f64>,
    encoder_offset_rad: Option<f64>,
    cascade_rate_hz: Option<f64>,
    position_kp: Option<f64>,
    position_ki: Option<f64>,
    position_kd: Option<f64>,
    max_velocity_rad_s: Option<f64>,
    velocity_kp: Option<f64>,
    velocity_ki: Option<f64>,
    velocity_kd: Option<f64>,
    cascade_max_current_a: Option<f64>,
    velocity_filter_alpha: Option<f64>,
    max_current_a: Option<f64>,
    overcurrent_trip_a: Option<f64>,
    bus_min_v: Option<f64>,
    bus_max_v: Option<f64>,
    max_abs_q_ref_rad: Option<f64>,
    max_abs_q_rad: Option<f64>,
    max_abs_qd_rad_s: Option<f64>,
    max_abs_qdd_rad_s2: Option<f64>,
    max_abs_tau_nm: Option<f64>,
    watchdog_ticks: Option<u16>,
    max_message_age_ticks: Option<u16>,
    bus_clock: Option<BusClockToml>,
    max_rate_error_ppm: Option<u32>,
    max_torque_nm: Option<f64>,
    max_torque_rate_nm_s: Option<f64>,
    max_lstm_correction_nm: Option<f64>,
    warmup_ticks: Option<u16>,
    lstm_retry_ticks: Option<u16>,
    feedforward_max_current_a: Option<f64>,
    bus_baud: Option<u32>,
    adaptation_time_constant_s: Option<f64>,
    max_adaptation_nm: Option<f64>,
    monitor_window_s: Option<f64>,
    monitor_fade_s: Option<f64>,
    monitor_hysteresis: Option<f64>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
enum BusClockToml {
    Synchronised,
    FreeRunning,
}

impl ProfileToml {
    /// The board's profile with every given field in its place (f64 to f32; a value
    /// beyond f32 becomes infinite and is refused by the range check).
    fn resolve(&self) -> firmware::control::JointProfile {
        use firmware::control::{BusClock, JointProfile};
        let mut p = JointProfile::BOARD;
        let set = |dst: &mut f32, v: Option<f64>| {
            if let Some(v) = v {
                *dst = v as f32;
            }
        };
        if let Some(v) = self.pole_pairs {
            p.motor.pole_pairs = v;
        }
        set(&mut p.motor.phase_resistance_ohm, self.phase_resistance_ohm);
        set(&mut p.motor.phase_inductance_h, self.phase_inductance_h);
        set(&mut p.motor.flux_linkage_wb, self.flux_linkage_wb);
        set(&mut p.gear_ratio, self.gear_ratio);
        set(&mut p.gear_efficiency, self.gear_efficiency);
        set(&mut p.encoder_offset_rad, self.encoder_offset_rad);
        set(&mut p.cascade.rate_hz, self.cascade_rate_hz);
        set(&mut p.cascade.position_kp, self.position_kp);
        set(&mut p.cascade.position_ki, self.position_ki);
        set(&mut p.cascade.position_kd, self.position_kd);
        set(&mut p.cascade.max_velocity_rad_s, self.max_velocity_rad_s);
        set(&mut p.cascade.velocity_kp, self.velocity_kp);
        set(&mut p.cascade.velocity_ki, self.velocity_ki);
        set(&mut p.cascade.velocity_kd, self.velocity_kd);
        set(&mut p.cascade.max_current_a, self.cascade_max_current_a);
        set(
            &mut p.cascade.velocity_filter_alpha,
            self.velocity_filter_alpha,
        );
        set(&mut p.max_current_a, self.max_current_a);
        set(&mut p.overcurrent_trip_a, self.overcurrent_trip_a);
        set(&mut p.bus_min_v, self.bus_min_v);
        set(&mut p.bus_max_v, self.bus_max_v);
        set(&mut p.max_abs_q_ref_rad, self.max_abs_q_ref_rad);
        set(&mut p.state_limits.max_abs_q_rad, self.max_abs_q_rad);
        set(&mut p.state_limits.max_abs_qd_rad_s, self.max_abs_qd_rad_s);
        set(
            &mut p.state_limits.max_abs_qdd_rad_s2,
            self.max_abs_qdd_rad_s2,
        );
        set(&mut p.state_limits.max_abs_tau_nm, self.max_abs_tau_nm);
        p.watchdog_ticks = self.watchdog_ticks.unwrap_or(p.watchdog_ticks);
        p.max_message_age_ticks = self
            .max_message_age_ticks
            .unwrap_or(p.max_message_age_ticks);
        let ppm = match (p.bus_clock, JointProfile::FREE_RUNNING) {
            (BusClock::FreeRunning { max_rate_error_ppm }, _)
            | (_, BusClock::FreeRunning { max_rate_error_ppm }) => max_rate_error_ppm,
            _ => 0,
        };
        let ppm = self.max_rate_error_ppm.unwrap_or(ppm);
        p.bus_clock = match (self.bus_clock, p.bus_clock) {
            (Some(BusClockToml::Synchronised), _) => BusClock::Synchronised,
            (Some(BusClockToml::FreeRunning), _) | (None, BusClock::FreeRunning { .. }) => {
                BusClock::FreeRunning {
                    max_rate_error_ppm: ppm,
                }
            }
            (None, BusClock::Synchronised) => BusClock::Synchronised,
        };
        set(&mut p.max_torque_nm, self.max_torque_nm);
        set(&mut p.max_torque_rate_nm_s, self.max_torque_rate_nm_s);
        set(&mut p.max_lstm_correction_nm, self.max_lstm_correction_nm);
        p.warmup_ticks = self.warmup_ticks.unwrap_or(p.warmup_ticks);
        p.lstm_retry_ticks = self.lstm_retry_ticks.unwrap_or(p.lstm_retry_ticks);
        set(
            &mut p.feedforward_max_current_a,
            self.feedforward_max_current_a,
        );
        p.bus_baud = self.bus_baud.unwrap_or(p.bus_baud);
        set(
            &mut p.adaptation.time_constant_s,
            self.adaptation_time_constant_s,
        );
        set(&mut p.adaptation.max_correction_nm, self.max_adaptation_nm);
        set(&mut p.monitor.window_s, self.monitor_window_s);
        set(&mut p.monitor.fade_s, self.monitor_fade_s);
        set(&mut p.monitor.hysteresis, self.monitor_hysteresis);
        p
    }
}

/// Line of `field = ...` in the `[joint.profile]` table of the `joint`-th
/// `[[joint]]` block, else of that table's header.
fn locate_profile(text: &str, joint: usize, field: &str) -> Option<usize> {
    let mut count = 0usize;
    let mut in_joint = false;
    let mut in_profile = false;
    let mut header = None;
    for (n, raw) in text.lines().enumerate() {
        let line = raw.trim_start();
        if line.starts_with("[[joint]]") {
            in_joint = count == joint;
            count += 1;
            in_profile = false;
            continue;
        }
        if line.starts_with('[') {
            in_profile = in_joint && line.starts_with("[joint.profile]");
            if in_profile {
                header = Some(n + 1);
            }
            continue;
        }
        if in_profile
            && let Some(rest) = line.strip_prefix(field)
            && rest.trim_start().starts_with('=')
        {
            return Some(n + 1);
        }
    }
    header
}

/// 1-based line of byte offset `pos` in `text`.
pub(super) fn line_of(text: &str, pos: usize) -> usize {
    text[..pos.min(text.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

/// Line of `field = ...` inside the `index`-th `[[joint]]` block (or at top level).
fn locate(text: &str, joint: Option<usize>, field: &str) -> Option<usize> {
    let mut block: Option<usize> = None;
    let mut count = 0usize;
    let mut in_top = true;
    for (n, raw) in text.lines().enumerate() {
        let line = raw.trim_start();
        if line.starts_with("[[joint]]") {
            block = Some(count);
            count += 1;
            in_top = false;
            continue;
        }
        if line.starts_with('[') {
            in_top = false;
            block = None;
            continue;
        }
        let here = match joint {
            Some(j) => block == Some(j),
            None => in_top,
        };
        if here
            && let Some(rest) = line.strip_prefix(field)
            && rest.trim_start().starts_with('=')
        {
            return Some(n + 1);
        }
    }
    if let Some(j) = joint {
        // The block header itself, when the field is missing.
        let mut c = 0usize;
        for (n, raw) in text.lines().enumerate() {
            if raw.trim_start().starts_with("[[joint]]") {
                if c == j {
                    return Some(n + 1);
                }
                c += 1;
            }
        }
    }
    None
}

fn rot_x(a: f64) -> Matrix3<f64> {
    Rotation3::from_axis_angle(&Vector3::x_axis(), a).into_inner()
}

fn rot_z(a: f64) -> Matrix3<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), a).into_inner()
}

pub(super) fn parse(text: &str, file: &Path) -> Result<Robot, RobotError> {
    let err = |line: Option<usize>, field: String, message: String| RobotError {
        file: file.to_path_buf(),
        line,
        field,
        message,
    };
    let parsed: DhFile = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, s.start));
        let msg = e.message().to_string();
        // The key on the offending line, qualified by its [[joint]] block; else the
        // key toml names in its message (missing/unknown fields).
        let quoted = msg
            .split('`')
            .nth(1)
            .filter(|k| k.chars().all(|c| c.is_alphanumeric() || c == '_'));
        // (At the end of the input the span points past the last key: look back.)
        let key_on_line = line.and_then(|l| {
            text.lines()
                .take(l)
                .collect::<Vec<_>>()
                .into_iter()
                .rev()
                .find_map(|t| {
                    let (k, _) = t.split_once('=')?;
                    let k = k.trim();
                    (!k.is_empty() && !k.starts_with('[') && !k.starts_with('#'))
                        .then(|| k.to_string())
                })
        });
        let key = quoted
            .map(str::to_string)
            .or(key_on_line)
            .unwrap_or_else(|| "<syntax>".to_string());
        let block = line.map(|l| {
            text.lines()
                .take(l)
                .filter(|t| t.trim_start().starts_with("[[joint]]"))
                .count()
        });
        let field = match block {
            Some(b) if b > 0 => format!("joint[{}].{key}", b - 1),
            _ => key,
        };
        err(line, field, msg)
    })?;
    if parsed.joint.is_empty() {
        return Err(err(None, "joint".into(), "no [[joint]] entries".into()));
    }
    let finite = |v: f64, j: Option<usize>, field: &str| -> Result<f64, RobotError> {
        if v.is_finite() {
            Ok(v)
        } else {
            let name = match j {
                Some(j) => format!("joint[{j}].{field}"),
                None => field.to_string(),
            };
            Err(err(
                locate(text, j, field),
                name,
                format!("not a finite number: {v}"),
            ))
        }
    };
    for g in parsed.gravity {
        finite(g, None, "gravity")?;
    }
    let mut terms = ModelTerms::default();
    if let Some(t) = &parsed.terms {
        terms.viscous_friction = t.viscous_friction.unwrap_or(terms.viscous_friction);
        terms.coulomb_friction = t.coulomb_friction.unwrap_or(terms.coulomb_friction);
        terms.friction_offset = t.friction_offset.unwrap_or(terms.friction_offset);
        terms.rotor_inertia = t.rotor_inertia.unwrap_or(terms.rotor_inertia);
        if let Some(eps) = t.coulomb_smoothing {
            if !(eps.is_finite() && eps > 0.0) {
                return Err(err(
                    None,
                    "terms.coulomb_smoothing".into(),
                    format!("must be a positive number of rad/s, got {eps}"),
                ));
            }
            terms.coulomb_smoothing_rad_s = Some(eps);
        }
    }
    let mut joints = Vec::with_capacity(parsed.joint.len());
    let mut prev_link: (Matrix3<f64>, Vector3<f64>) = (Matrix3::identity(), Vector3::zeros());
    for (i, j) in parsed.joint.iter().enumerate() {
        let at = |field: &str| locate(text, Some(i), field);
        let fe =
            |field: &str, message: String| err(at(field), format!("joint[{i}].{field}"), message);
        for (v, f) in [
            (j.a, "a"),
            (j.alpha, "alpha"),
            (j.d, "d"),
            (j.theta_offset, "theta_offset"),
            (j.mass, "mass"),
        ] {
            finite(v, Some(i), f)?;
        }
        for v in j.com {
            finite(v, Some(i), "com")?;
        }
        for v in j.inertia {
            finite(v, Some(i), "inertia")?;
        }
        if j.mass < 0.0 {
            return Err(fe("mass", format!("negative mass {} kg", j.mass)));
        }
        let ic = inertia_matrix(&j.inertia);
        let eig = ic.symmetric_eigenvalues();
        let scale = eig.amax().max(1e-12);
        if eig.iter().any(|&e| e < -1e-9 * scale) {
            return Err(fe(
                "inertia",
                format!(
                    "not positive semi-definite (eigenvalues {:?})",
                    eig.as_slice()
                ),
            ));
        }
        let rows = [
            [ic[(0, 0)], ic[(0, 1)], ic[(0, 2)]],
            [ic[(1, 0)], ic[(1, 1)], ic[(1, 2)]],
            [ic[(2, 0)], ic[(2, 1)], ic[(2, 2)]],
        ];
        artifacts::plausible::rigid_body(j.mass, &rows).map_err(|m| fe("inertia", m))?;
        let opt = |v: Option<f64>, f: &str, positive: bool| -> Result<Option<f64>, RobotError> {
            match v {
                None => Ok(None),
                Some(x) if !x.is_finite() => Err(fe(f, format!("not a finite number: {x}"))),
                Some(x) if positive && x <= 0.0 => Err(fe(f, format!("must be positive, got {x}"))),
                Some(x) => Ok(Some(x)),
            }
        };
        let limits = JointLimits {
            q_min_rad: opt(j.q_min, "q_min", false)?,
            q_max_rad: opt(j.q_max, "q_max", false)?,
            qd_max_rad_s: opt(j.qd_max, "qd_max", true)?,
            qdd_max_rad_s2: opt(j.qdd_max, "qdd_max", true)?,
            effort_max_nm: opt(j.effort_max, "effort_max", true)?,
        };
        if let (Some(lo), Some(hi)) = (limits.q_min_rad, limits.q_max_rad) {
            // The same check as a URDF joint's <limit>: ordered and distinct.
            artifacts::plausible::limits(lo, hi).map_err(|m| fe("q_max", m))?;
        }
        let drive = JointDrive {
            drive_gain_nm_per_a: opt(j.drive_gain_nm_per_a, "drive_gain_nm_per_a", true)?,
            gear_ratio: opt(j.gear_ratio, "gear_ratio", true)?,
            torque_constant_nm_per_a: opt(
                j.torque_constant_nm_per_a,
                "torque_constant_nm_per_a",
                true,
            )?,
            rotor_inertia_kg_m2: opt(j.rotor_inertia, "rotor_inertia", false)?,
        };
        if drive.rotor_inertia_kg_m2.is_some_and(|x| x < 0.0) {
            return Err(fe("rotor_inertia", "must not be negative".into()));
        }
        for (v, f) in [
            (j.friction_viscous, "friction_viscous"),
            (j.friction_coulomb, "friction_coulomb"),
            (j.friction_offset, "friction_offset"),
        ] {
            finite(v, Some(i), f)?;
        }
        let mode = match opt(j.locked_at, "locked_at", false)? {
            Some(q) => JointMode::Locked { q_rad: q },
            None => JointMode::Modelled,
        };
        let profile = match &j.profile {
            None => None,
            Some(t) => {
                let p = t.resolve();
                if let Some(field) = p.invalid_field() {
                    return Err(err(
                        locate_profile(text, i, field),
                        format!("joint[{i}].profile.{field}"),
                        "out of range: rates, limits, motor constants and the gear must be \
                         positive and finite, gains finite and not negative, gear_efficiency \
                         and velocity_filter_alpha in (0, 1], overcurrent_trip_a above \
                         max_current_a, bus_max_v above bus_min_v, tick counts at least 1, \
                         max_rate_error_ppm below 1000000"
                            .into(),
                    ));
                }
                Some(p)
            }
        };
        let own_link = (rot_x(j.alpha), Vector3::new(j.a, 0.0, 0.0));
        let (origin_rotation, origin_translation, link_frame) = match parsed.convention {
            DhConvention::Standard => {
                // F_i = DH_{i-1} * Tz(d_i) Rz(offset_i) Rz(q_i); DH_{i-1} = F_{i-1} * Tx(a_{i-1}) Rx(alpha_{i-1}).
                let (pr, pp) = prev_link;
                let r = pr * rot_z(j.theta_offset);
                let p = pp + pr * Vector3::new(0.0, 0.0, j.d);
                prev_link = own_link;
                (r, p, Some(own_link))
            }
            DhConvention::Modified => {
                let r = rot_x(j.alpha) * rot_z(j.theta_offset);
                let p = Vector3::new(j.a, 0.0, 0.0) + rot_x(j.alpha) * Vector3::new(0.0, 0.0, j.d);
                (r, p, None)
            }
        };
        joints.push(Joint {
            name: j.name.clone(),
            origin_rotation,
            origin_translation,
            axis: Vector3::z_axis(),
            link_frame,
            inertial: LinkInertial {
                mass_kg: j.mass,
                com_m: Vector3::from(j.com),
                inertia_com: ic,
            },
            limits,
            drive,
            friction: JointFriction {
                viscous_nm_s_rad: j.friction_viscous,
                coulomb_nm: j.friction_coulomb,
                offset_nm: j.friction_offset,
            },
            mode,
            profile,
        });
    }
    if parsed
        .terms
        .as_ref()
        .and_then(|t| t.rotor_inertia)
        .is_none()
    {
        terms.rotor_inertia = joints.iter().any(|j| j.drive.rotor_inertia_kg_m2.is_some());
    }
    Ok(Robot {
        name: parsed.name,
        source: file.to_path_buf(),
        gravity: Vector3::from(parsed.gravity),
        joints,
        terms,
        identified_ranges: Vec::new(),
    })
}
