//! The current loop, the space-vector modulation and the drive's electrical angle and
//! speed against values worked out by hand from the motor, the gains and the geometry
//! (not from the implementation): measured currents, decoupling voltages, phase voltages
//! about the star point, the feedforward's sum, and a zero or over-range bus.

mod common;

use firmware::control::foc::{self, AlphaBeta, Dq};
use firmware::control::*;
use std::f32::consts::{PI, TAU};

/// The shared test drive; without `gains`, its outer loops' gains are zero (the
/// feedforward alone commands the current).
fn config(gains: bool) -> DriveConfig {
    let mut c = common::drive_config();
    if !gains {
        let k = &mut c.cascade;
        (k.position_kp, k.position_ki, k.position_kd) = (0.0, 0.0, 0.0);
        (k.velocity_kp, k.velocity_ki, k.velocity_kd) = (0.0, 0.0, 0.0);
    }
    c
}

fn sample(angle: f32, ia: f32, ib: f32) -> SensorSample {
    SensorSample {
        phase_current_a: [ia, ib],
        motor_angle_rad: angle,
        bus_v: 48.0,
    }
}

/// drive.rs:236/238: a step of exactly +-pi is taken literally (no wrap).
#[test]
fn an_exact_half_turn_step_is_taken_literally() {
    let mut d = JointDrive::new(config(true));
    d.pwm_tick(&sample(0.0, 0.0, 0.0));
    d.pwm_tick(&sample(PI, 0.0, 0.0));
    assert!((d.q_rad() - PI / 100.0).abs() < 1e-6, "{}", d.q_rad());
    let mut d = JointDrive::new(config(true));
    d.pwm_tick(&sample(PI, 0.0, 0.0));
    d.pwm_tick(&sample(0.0, 0.0, 0.0));
    assert!((d.q_rad() + PI / 100.0).abs() < 1e-6, "{}", d.q_rad());
}

/// drive.rs:270: the held feedforward adds to the outer loops' command.
#[test]
fn the_feedforward_adds_to_the_outer_loop_command() {
    let mut d = JointDrive::new(config(false));
    d.set_feedforward_current(2.0);
    let o = d.pwm_tick(&sample(1.0, 0.0, 0.0));
    assert_eq!(o.iq_ref_a, 2.0, "{o:?}");
}

/// drive.rs:277: the Park transform uses pole pairs * (encoder - offset).
#[test]
fn the_measured_q_current_uses_the_electrical_angle() {
    for angle in [1.0f32, 2.5, 4.0] {
        let th = 7.0 * (angle - 0.1);
        let i = 5.0;
        let ia = -i * th.sin();
        let ib = -i * (th - 2.0 * PI / 3.0).sin();
        let mut d = JointDrive::new(config(false));
        let o = d.pwm_tick(&sample(angle, ia, ib));
        assert!((o.iq_meas_a - i).abs() < 1e-2, "angle {angle}: {o:?}");
    }
}

/// q voltage from the duties (linear range), at electrical angle `th`.
fn vdq_from_duties(duties: [f32; 3], bus: f32, th: f32) -> Dq {
    let [a, b, c] = foc::duties_to_phase_voltages(duties, bus);
    foc::park(foc::clarke3(a, b, c), th.sin(), th.cos())
}

/// drive.rs:278: the back-EMF decoupling uses pole pairs * gear * joint speed.
#[test]
fn the_decoupling_voltage_follows_the_joint_speed() {
    // At rest with no current: no voltage.
    let mut d = JointDrive::new(config(false));
    let o = d.pwm_tick(&sample(1.0, 0.0, 0.0));
    assert_eq!(o.duties, [0.5; 3], "{o:?}");
    // Turning at 1 rad/s of joint: vq = 7 * 100 * qd * flux linkage.
    let mut d = JointDrive::new(config(false));
    let mut o = DriveOutput::default();
    let mut angle = 0.0;
    for k in 0..400 {
        angle = (0.2 + 0.005 * k as f32).rem_euclid(TAU);
        o = d.pwm_tick(&sample(angle, 0.0, 0.0));
    }
    let v = vdq_from_duties(o.duties, 48.0, 7.0 * (angle - 0.1));
    let want = 7.0 * 100.0 * o.qd_rad_s * 0.01;
    assert!((o.qd_rad_s - 1.0).abs() < 0.05, "{o:?}");
    assert!(
        (v.q - want).abs() < 1e-2 && v.d.abs() < 1e-2,
        "{v:?} vs {want}"
    );
}

/// foc.rs:84: a zero bus gives zero voltage.
#[test]
fn a_zero_bus_gives_half_duties() {
    for bus in [0.0f32, -0.0] {
        let d = foc::space_vector_duties(
            AlphaBeta {
                alpha: 1.0,
                beta: 0.0,
            },
            bus,
        );
        assert_eq!(d, [0.5; 3]);
    }
}

/// foc.rs:97: beyond the linear range the duties saturate at 1 and 0.
#[test]
fn an_over_range_vector_saturates_the_duties() {
    let d = foc::space_vector_duties(
        AlphaBeta {
            alpha: 100.0,
            beta: 0.0,
        },
        48.0,
    );
    assert_eq!(d, [1.0, 0.0, 0.0]);
}

/// foc.rs:110: the phase voltages are relative to the star point (sum zero).
#[test]
fn phase_voltages_are_relative_to_the_star_point() {
    let v = foc::duties_to_phase_voltages([0.9, 0.2, 0.4], 10.0);
    for (x, w) in v.iter().zip([4.0, -3.0, -1.0]) {
        assert!((x - w).abs() < 1e-5, "{v:?}");
    }
}

/// foc.rs:198: kt = 1.5 * pole pairs * flux linkage.
#[test]
fn the_board_motor_torque_constant() {
    let kt = MotorParameters::BOARD.torque_constant_nm_per_a();
    assert!((kt - 0.105).abs() < 1e-6, "{kt}");
}

fn loop_at(decoupling: bool) -> CurrentLoop {
    CurrentLoop::new(CurrentLoopConfig {
        decoupling,
        ..CurrentLoopConfig::tuned(MotorParameters::BOARD, 20_000.0)
    })
}

/// Phase currents a, b of a dq current at electrical angle 0.
fn ab_at_zero(d: f32, q: f32) -> [f32; 2] {
    [d, -0.5 * d + 0.866_025_4 * q]
}

/// foc.rs:297/298: the PI acts on reference - measured current on both axes.
#[test]
fn the_pi_acts_on_the_current_error() {
    let mut cl = loop_at(false);
    let out = cl.step(ab_at_zero(2.0, 0.5), 0.0, 0.0, 48.0, Dq { d: 0.0, q: 1.0 });
    let g = 3e-4 * 6000.0 + 0.3 * 6000.0 / 20_000.0; // kp + ki * dt
    assert!((out.v_dq_v.d - g * -2.0).abs() < 1e-3, "{out:?}");
    assert!((out.v_dq_v.q - g * 0.5).abs() < 1e-3, "{out:?}");
}

/// foc.rs:302/303: the decoupling terms -w L iq and w (L id + psi).
#[test]
fn the_decoupling_terms() {
    let mut cl = loop_at(true);
    let out = cl.step(
        ab_at_zero(2.0, 3.0),
        0.0,
        1000.0,
        48.0,
        Dq { d: 2.0, q: 3.0 },
    );
    assert!(!out.voltage_limited);
    assert!((out.v_dq_v.d - -0.9).abs() < 1e-3, "{out:?}");
    assert!((out.v_dq_v.q - 10.6).abs() < 1e-3, "{out:?}");
}
