//! The joint drive's position and latched faults against their specification: the
//! first valid encoder reading is joint position 0, after which the joint moves by
//! the motor's travel (counted across turns) over the gear ratio; latched faults stay
//! until cleared.

mod common;

use common::drive_config as config;
use firmware::control::*;
use std::f32::consts::TAU;

fn sample(motor_angle_rad: f32) -> SensorSample {
    SensorSample {
        phase_current_a: [0.0, 0.0],
        motor_angle_rad: motor_angle_rad.rem_euclid(TAU),
        bus_v: 48.0,
    }
}

#[test]
fn the_joint_moves_by_the_motor_travel_over_the_gear_ratio() {
    for step in [0.5f32, -0.7] {
        let mut drive = JointDrive::new(config());
        let start = 1.0f32;
        drive.pwm_tick(&sample(start));
        assert_eq!(drive.q_rad(), 0.0);
        for k in 1..=40 {
            drive.pwm_tick(&sample(start + step * k as f32));
            // 40 steps of 0.5 rad: 20 rad of motor, over 3 turns; joint 0.2 rad.
            let want = step * k as f32 / 100.0;
            assert!(
                (drive.q_rad() - want).abs() < 1e-5,
                "step {step}, tick {k}: {} vs {want}",
                drive.q_rad()
            );
        }
    }
}

#[test]
fn latched_faults_stay_until_cleared() {
    let mut drive = JointDrive::new(config());
    drive.pwm_tick(&sample(0.3));
    let mut bad = sample(0.3);
    bad.bus_v = f32::NAN;
    let out = drive.pwm_tick(&bad);
    assert!(!out.bridge_enabled);
    assert!(!drive.latched_faults().is_empty());
    // Good samples again: the fault stays latched until it is cleared.
    for _ in 0..10 {
        drive.pwm_tick(&sample(0.3));
    }
    assert!(!drive.latched_faults().is_empty());
    drive.clear_latched();
    assert!(drive.latched_faults().is_empty());
}

#[test]
fn the_velocity_estimate_settles_on_the_joint_speed() {
    // 20 kHz PWM, outer loop at 5 kHz: a motor step of s rad per PWM tick is a joint
    // speed of s / 100 * 20 000 rad/s.
    for step in [0.05f32, -0.07] {
        let mut drive = JointDrive::new(config());
        for k in 0..400 {
            drive.pwm_tick(&sample(0.2 + step * k as f32));
        }
        let want = step / 100.0 * 20_000.0;
        assert!(
            (drive.qd_rad_s() - want).abs() < 1e-2 * want.abs(),
            "{} vs {want}",
            drive.qd_rad_s()
        );
    }
}

#[test]
fn a_phase_current_trips_the_bridge_only_above_the_trip_level() {
    for phase in 0..2 {
        for (amps, trips) in [(20.0f32, false), (20.0f32.next_up(), true)] {
            let mut drive = JointDrive::new(config());
            let mut s = sample(0.3);
            s.phase_current_a[phase] = amps;
            let out = drive.pwm_tick(&s);
            assert_eq!(
                drive.latched_faults().contains(FaultFlags::OVERCURRENT),
                trips,
                "phase {phase}, {amps} A"
            );
            assert_eq!(out.bridge_enabled, !trips, "phase {phase}, {amps} A");
        }
    }
}
