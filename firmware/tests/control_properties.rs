//! Property tests of the control loop: 10 million random ticks in total (6 M drive
//! PWM ticks, 4 M compensator ticks) with NaN, +-inf, huge values, garbage
//! predictions and stale or out-of-order messages. Every output must be finite and
//! within its limits, and the fault flags must say why an input was not used.

use firmware::control::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const DRIVE_TICKS: u32 = 6_000_000;
const COMPENSATOR_TICKS: u32 = 4_000_000;

/// A value from a mix: mostly plausible, sometimes special or huge.
fn nasty(rng: &mut ChaCha8Rng, plausible: f32) -> f32 {
    match rng.gen_range(0..40) {
        0 => f32::NAN,
        1 => f32::INFINITY,
        2 => f32::NEG_INFINITY,
        3 => f32::MAX,
        4 => -f32::MAX,
        5 => rng.gen_range(-1e30..1e30),
        6 => f32::MIN_POSITIVE,
        7 => rng.gen_range(-10.0..10.0) * plausible,
        _ => rng.gen_range(-1.0..1.0) * plausible,
    }
}

fn drive_config() -> DriveConfig {
    DriveConfig {
        current: CurrentLoopConfig::tuned(MotorParameters::BOARD, 20_000.0),
        cascade: CascadeConfig {
            rate_hz: 5000.0,
            position_kp: 50.0,
            position_ki: 1.0,
            position_kd: 0.01,
            max_velocity_rad_s: 3.0,
            velocity_kp: 5.0,
            velocity_ki: 50.0,
            velocity_kd: 0.001,
            max_current_a: 10.0,
            velocity_filter_alpha: 0.2,
        },
        gear_ratio: 100.0,
        encoder_offset_rad: 0.1,
        max_current_a: 12.0,
        overcurrent_trip_a: 20.0,
        bus_min_v: 18.0,
        bus_max_v: 60.0,
        max_abs_q_ref_rad: 7.0,
    }
}

#[test]
fn drive_outputs_stay_finite_and_within_limits() {
    let cfg = drive_config();
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_d71e);
    let mut drive = JointDrive::new(cfg);
    let mut angle = 0.0f32;
    let mut counts = [0u32; 4]; // sensor faults, overcurrent, bus, reference
    for _ in 0..DRIVE_TICKS {
        angle = (angle + rng.gen_range(-0.2..0.2f32)).rem_euclid(core::f32::consts::TAU);
        let mut sample = SensorSample {
            phase_current_a: [rng.gen_range(-12.0..12.0), rng.gen_range(-12.0..12.0)],
            motor_angle_rad: angle,
            bus_v: rng.gen_range(16.0..62.0),
        };
        let corrupt = rng.gen_range(0..20) == 0;
        if corrupt {
            match rng.gen_range(0..4) {
                0 => sample.phase_current_a[0] = nasty(&mut rng, 30.0),
                1 => sample.phase_current_a[1] = nasty(&mut rng, 30.0),
                2 => sample.motor_angle_rad = nasty(&mut rng, 20.0),
                _ => sample.bus_v = nasty(&mut rng, 100.0),
            }
        }
        let mut bad_reference = false;
        if rng.gen_range(0..8) == 0 {
            let r = JointReference {
                q_rad: nasty(&mut rng, 7.0),
                qd_rad_s: nasty(&mut rng, 3.0),
                qdd_rad_s2: nasty(&mut rng, 50.0),
            };
            bad_reference =
                !(r.q_rad.abs() <= 7.0 && r.qd_rad_s.abs() <= 3.0 && r.qdd_rad_s2.is_finite());
            drive.set_reference(&r);
        }
        if rng.gen_range(0..8) == 0 {
            let ff = nasty(&mut rng, 15.0);
            bad_reference |= !ff.is_finite();
            drive.set_feedforward_current(ff);
        }
        let o = drive.pwm_tick(&sample);

        assert!(
            o.duties.iter().all(|d| (0.0..=1.0).contains(d)),
            "{o:?} from {sample:?}"
        );
        assert!(o.iq_ref_a.abs() <= cfg.max_current_a, "{o:?}");
        assert!(
            o.q_rad.is_finite() && o.qd_rad_s.is_finite() && o.iq_meas_a.is_finite(),
            "{o:?}"
        );
        let [ia, ib] = sample.phase_current_a;
        let sensors_finite = ia.is_finite() && ib.is_finite() && sample.bus_v.is_finite();
        let angle_ok = sample.motor_angle_rad.abs() <= 4.0 * core::f32::consts::PI;
        if !sensors_finite || !angle_ok {
            assert!(
                o.faults.contains(FaultFlags::SENSOR_INVALID),
                "{o:?} from {sample:?}"
            );
        }
        let tripped = ia.abs() > 20.0 || ib.abs() > 20.0 || (ia + ib).abs() > 20.0;
        let bus_bad = !(18.0..=60.0).contains(&sample.bus_v);
        let should_be_off = !sensors_finite || !angle_ok || tripped || bus_bad;
        assert_eq!(o.bridge_enabled, !should_be_off, "{o:?} from {sample:?}");
        if !o.bridge_enabled {
            assert_eq!(o.duties, [0.5; 3]);
            assert!(o.faults.intersects(
                FaultFlags::SENSOR_INVALID | FaultFlags::OVERCURRENT | FaultFlags::BUS_VOLTAGE
            ));
            counts[0] += o.faults.contains(FaultFlags::SENSOR_INVALID) as u32;
            counts[1] += o.faults.contains(FaultFlags::OVERCURRENT) as u32;
            counts[2] += o.faults.contains(FaultFlags::BUS_VOLTAGE) as u32;
        }
        if bad_reference {
            assert!(o.faults.contains(FaultFlags::REFERENCE_INVALID), "{o:?}");
            counts[3] += 1;
        }
        assert!(drive.reference().q_rad.abs() <= 7.0 && drive.reference().qd_rad_s.abs() <= 3.0);
    }
    println!(
        "drive: {DRIVE_TICKS} ticks; sensor-invalid / overcurrent / bus / reference faults: {counts:?}"
    );
    assert!(
        counts.iter().all(|&c| c > 1000),
        "every fault kind exercised: {counts:?}"
    );
}

/// A predictor returning whatever the test puts in `next`.
struct Scripted {
    next: [f32; 3],
    resets: u64,
}
impl TorquePredictor<3> for Scripted {
    fn predict_nm(&mut self, _input: &PredictorInput<3>) -> [f32; 3] {
        self.next
    }
    fn reset(&mut self) {
        self.resets += 1;
    }
}

fn compensator_config() -> CompensatorConfig {
    CompensatorConfig {
        rate_hz: 1000.0,
        own_joint: 1,
        state_limits: StateLimits {
            max_abs_q_rad: 7.0,
            max_abs_qd_rad_s: 5.0,
            max_abs_qdd_rad_s2: 100.0,
            max_abs_tau_nm: 300.0,
        },
        watchdog_ticks: 3,
        max_message_age_us: 5_000,
        max_torque_nm: 120.0,
        max_torque_rate_nm_s: 20_000.0,
        max_lstm_correction_nm: 20.0,
        warmup_ticks: 8,
        lstm_retry_ticks: 6,
        drive_gain_nm_per_a: 10.0,
        max_current_a: 10.0,
    }
}

fn random_state(rng: &mut ChaCha8Rng, corrupt: bool) -> JointState {
    let mut a = [
        rng.gen_range(-6.0..6.0),
        rng.gen_range(-4.0..4.0),
        rng.gen_range(-90.0..90.0),
        rng.gen_range(-6.0..6.0),
        rng.gen_range(-4.0..4.0),
        rng.gen_range(-250.0..250.0),
    ];
    if corrupt {
        let i = rng.gen_range(0..6);
        a[i] = nasty(rng, 400.0);
    }
    JointState::from_array(a)
}

#[test]
fn compensator_outputs_stay_finite_and_within_limits() {
    let cfg = compensator_config();
    let mut rng = ChaCha8Rng::seed_from_u64(0xc0ffee);
    let model = Scripted {
        next: [0.0; 3],
        resets: 0,
    };
    let lstm = Scripted {
        next: [0.0; 3],
        resets: 0,
    };
    let mut comp: Compensator<3, Scripted, Scripted> = Compensator::new(cfg, model, lstm).unwrap();
    let mut prev = 0.0f32;
    let mut seq = [0u16; 3];
    let mut now_us = 0u32;
    let mut sources = [0u32; 3];
    let mut flags_seen = FaultFlags::NONE;
    let step = cfg.max_torque_rate_nm_s / cfg.rate_hz;
    for _ in 0..COMPENSATOR_TICKS {
        now_us = now_us.wrapping_add(1000);
        let mut rejected = false;
        let mut out_of_order = false;
        // Messages from joints 0 and 2: usually one fresh each, sometimes none
        // (stale), corrupt, replayed, late-stamped, or for a wrong joint.
        for j in [0u8, 2] {
            if rng.gen_range(0..30) == 0 {
                continue;
            }
            let corrupt = rng.gen_range(0..25) == 0;
            let replay = rng.gen_range(0..40) == 0;
            if !replay {
                seq[j as usize] = seq[j as usize].wrapping_add(rng.gen_range(1..3));
            }
            let late = if rng.gen_range(0..50) == 0 {
                rng.gen_range(0..20_000)
            } else {
                0
            };
            let joint = if rng.gen_range(0..200) == 0 {
                rng.gen_range(0..=255)
            } else {
                j
            };
            let m = JointStateMessage {
                joint,
                sequence: seq[j as usize],
                timestamp_us: now_us.wrapping_sub(late),
                state: random_state(&mut rng, corrupt),
            };
            let f = comp.receive(&m);
            let bad = corrupt && !cfg.state_limits.accepts(&m.state) || (joint != 0 && joint != 2);
            if bad {
                assert_eq!(f, FaultFlags::STATE_REJECTED);
            }
            rejected |= f.contains(FaultFlags::STATE_REJECTED);
            out_of_order |= f.contains(FaultFlags::STATE_OUT_OF_ORDER);
        }
        // Predictions: plausible, or garbage.
        let model_nm = nasty(&mut rng, 150.0);
        let lstm_nm = if rng.gen_range(0..4) == 0 {
            nasty(&mut rng, 300.0)
        } else {
            model_nm + rng.gen_range(-10.0..10.0)
        };
        comp.model_mut().next = [rng.gen_range(-1.0..1.0), model_nm, f32::NAN];
        comp.lstm_mut().next = [f32::INFINITY, lstm_nm, 0.0];
        let own_corrupt = rng.gen_range(0..30) == 0;
        let own = random_state(&mut rng, own_corrupt);
        let o = comp.tick(&own, now_us);

        // Always finite and within limits.
        assert!(
            o.torque_nm.is_finite() && o.torque_nm.abs() <= cfg.max_torque_nm,
            "{o:?}"
        );
        assert!(
            o.current_a.is_finite() && o.current_a.abs() <= cfg.max_current_a,
            "{o:?}"
        );
        assert!(
            (o.torque_nm - prev).abs() <= step * 1.0001,
            "rate: {prev} -> {o:?}"
        );
        prev = o.torque_nm;
        // The flags say why.
        if rejected {
            assert!(o.faults.contains(FaultFlags::STATE_REJECTED));
        }
        if out_of_order {
            assert!(o.faults.contains(FaultFlags::STATE_OUT_OF_ORDER));
        }
        if !cfg.state_limits.accepts(&own) {
            assert!(o.faults.contains(FaultFlags::OWN_STATE_INVALID), "{o:?}");
        }
        let input_fault = FaultFlags::OWN_STATE_INVALID | FaultFlags::STATE_STALE;
        match o.source {
            FeedforwardSource::Zero => {
                assert!(
                    o.faults.intersects(input_fault | FaultFlags::MODEL_INVALID),
                    "{o:?}"
                );
                sources[0] += 1;
            }
            FeedforwardSource::Model => {
                assert!(
                    !o.faults.intersects(input_fault | FaultFlags::MODEL_INVALID),
                    "{o:?}"
                );
                assert!(model_nm.abs() <= 300.0);
                sources[1] += 1;
            }
            FeedforwardSource::ModelLstm => {
                assert!(
                    !o.faults.intersects(input_fault | FaultFlags::MODEL_INVALID),
                    "{o:?}"
                );
                assert!(
                    !o.faults
                        .intersects(FaultFlags::LSTM_INVALID | FaultFlags::LSTM_IMPLAUSIBLE)
                );
                assert!(lstm_nm.abs() <= 300.0 && (lstm_nm - model_nm).abs() <= 20.0);
                sources[2] += 1;
            }
        }
        let model_bad = model_nm.is_nan() || model_nm.abs() > 300.0;
        if !o.faults.intersects(input_fault) && model_bad {
            assert!(
                o.faults.contains(FaultFlags::MODEL_INVALID) && o.source == FeedforwardSource::Zero
            );
        }
        if o.faults
            .intersects(FaultFlags::LSTM_INVALID | FaultFlags::LSTM_IMPLAUSIBLE)
        {
            assert_eq!(o.source, FeedforwardSource::Model);
        }
        flags_seen |= o.faults;
    }
    println!(
        "compensator: {COMPENSATOR_TICKS} ticks; zero / model / model+LSTM: {sources:?}; flags seen {:#06x}",
        flags_seen.bits()
    );
    assert!(sources.iter().all(|&c| c > 10_000), "{sources:?}");
    for f in [
        FaultFlags::STATE_REJECTED,
        FaultFlags::STATE_STALE,
        FaultFlags::STATE_OUT_OF_ORDER,
        FaultFlags::OWN_STATE_INVALID,
        FaultFlags::MODEL_INVALID,
        FaultFlags::LSTM_INVALID,
        FaultFlags::LSTM_IMPLAUSIBLE,
        FaultFlags::FF_RATE_LIMITED,
        FaultFlags::FF_MAGNITUDE_LIMITED,
        FaultFlags::FF_WARMUP,
    ] {
        assert!(flags_seen.contains(f), "never exercised: {f:?}");
    }
}

/// The compensator with the board's real stages (the compiled-in dynamics on the
/// wrist and the compiled-in LSTM through `LstmPredictor`) on random states, some of
/// them NaN, infinite, huge or stale: outputs finite and within limits, and a
/// feedforward from the LSTM only when every input was valid.
#[test]
fn compiled_in_model_and_lstm_stay_finite_and_within_limits() {
    use firmware::model::default as m;
    const TICKS: u32 = 50_000;
    // A tight plausibility bound so that the LSTM -> model fallback happens too.
    let cfg = CompensatorConfig {
        max_lstm_correction_nm: 2.0,
        ..compensator_config()
    };
    let model = SubsetModel {
        model: &m::DYNAMICS,
        joints: firmware::model::dynamics_indices(m::JOINT_INDICES, m::DYNAMICS_JOINTS),
        fixed_q_rad: [0.0; m::DYNAMICS_JOINTS],
    };
    let lstm = LstmPredictor::<_, 3, { m::INPUTS }>::new(&m::NETWORK, m::FEATURE_PRESET).unwrap();
    let mut comp = Compensator::<3, _, _>::new(cfg, model, lstm).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(0xfeed);
    let mut now_us = 0u32;
    let mut seq = 0u16;
    let mut sources = [0u32; 3];
    for _ in 0..TICKS {
        now_us = now_us.wrapping_add(1000);
        seq = seq.wrapping_add(1);
        for j in [0u8, 2] {
            if rng.gen_range(0..50) == 0 {
                continue; // stale
            }
            let corrupt = rng.gen_range(0..30) == 0;
            let _ = comp.receive(&JointStateMessage {
                joint: j,
                sequence: seq,
                timestamp_us: now_us,
                state: random_state(&mut rng, corrupt),
            });
        }
        let own_corrupt = rng.gen_range(0..30) == 0;
        let own = random_state(&mut rng, own_corrupt);
        let o = comp.tick(&own, now_us);
        assert!(
            o.torque_nm.is_finite() && o.torque_nm.abs() <= cfg.max_torque_nm,
            "{o:?}"
        );
        assert!(
            o.current_a.is_finite() && o.current_a.abs() <= cfg.max_current_a,
            "{o:?}"
        );
        if o.source == FeedforwardSource::ModelLstm {
            assert!(cfg.state_limits.accepts(&own));
            assert!(!o.faults.intersects(
                FaultFlags::OWN_STATE_INVALID | FaultFlags::STATE_STALE | FaultFlags::MODEL_INVALID
            ));
        }
        if !cfg.state_limits.accepts(&own) {
            assert!(o.faults.contains(FaultFlags::OWN_STATE_INVALID));
            assert_eq!(o.source, FeedforwardSource::Zero);
        }
        if o.faults
            .intersects(FaultFlags::LSTM_INVALID | FaultFlags::LSTM_IMPLAUSIBLE)
        {
            assert_eq!(o.source, FeedforwardSource::Model);
        }
        sources[o.source as usize] += 1;
    }
    println!("compiled-in stages: {TICKS} ticks; zero / model / model+LSTM: {sources:?}");
    assert!(sources.iter().all(|&c| c > 100), "{sources:?}");
}
