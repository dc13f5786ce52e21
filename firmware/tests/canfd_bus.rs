//! Hostile frames on the CAN-FD state bus, in both clock modes (SYNC bus time, the
//! default, and free-running clocks): one receiving drive (joint index 1 of three)
//! hears joints 0 and 2 through [`BusNode`], and a hostile node replays, delays,
//! forges, corrupts or replaces their frames. Every state a prediction reads is
//! traced back to the frame that carried it (its measured position is a unique
//! frame number): it must be an authentic frame of its real sender, at most the
//! bound old in true time. The senders' clocks are the test's.

use std::collections::HashMap;

use firmware::control::canfd::{
    BitRates, BusBudget, BusNode, BusTime, BusTimeConfig, BusTimeSource, CanFdFrame, FrameAuth,
    STATE_LEN, StateFrame, SyncFrame,
};
use firmware::control::{
    BusClock, Compensator, CompensatorConfig, CompensatorOutput, FaultFlags, FeedforwardSource,
    JointState, JointStateMessage, NoPredictor, PredictorInput, StateLimits, TorquePredictor,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const KEY: [u8; 16] = *b"test-robot-key-A";
const TICK_US: u32 = 10_000; // 100 Hz, the default model's control rate
const MAX_AGE_US: u32 = 3 * TICK_US;
const RATE_PPM: u32 = 20_000;
/// The receiver's local clock: true time plus this.
const LOCAL_OFFSET_US: u32 = 123_456_789;
/// The SYNC master's bus time: true time plus this.
const BUS_OFFSET_US: u32 = 4_000_000_000;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    Sync,
    FreeRunning,
}

const MODES: [Mode; 2] = [Mode::Sync, Mode::FreeRunning];

/// Model: 2 * own q_ref + the others' q_ref; keeps the states of its last call.
#[derive(Default)]
struct Recorder {
    seen: Option<[JointState; 3]>,
}

impl TorquePredictor<3> for Recorder {
    fn predict_nm(&mut self, input: &PredictorInput<3>) -> [f32; 3] {
        self.seen = Some(input.joints);
        let j = &input.joints;
        let t = 2.0 * j[1].q_ref_rad + j[0].q_ref_rad + j[2].q_ref_rad;
        [t; 3]
    }
    fn reset(&mut self) {}
}

fn config(mode: Mode) -> CompensatorConfig {
    CompensatorConfig {
        rate_hz: 1e6 / TICK_US as f32,
        own_joint: 1,
        state_limits: StateLimits {
            max_abs_q_rad: 7.0,
            max_abs_qd_rad_s: 5.0,
            max_abs_qdd_rad_s2: 100.0,
            max_abs_tau_nm: 300.0,
        },
        watchdog_ticks: 3,
        max_message_age_us: MAX_AGE_US,
        bus_clock: match mode {
            Mode::Sync => BusClock::Synchronised,
            Mode::FreeRunning => BusClock::FreeRunning {
                max_rate_error_ppm: RATE_PPM,
            },
        },
        max_torque_nm: 120.0,
        max_torque_rate_nm_s: 2_000.0,
        max_lstm_correction_nm: 30.0,
        warmup_ticks: 10,
        lstm_retry_ticks: 50,
        drive_gain_nm_per_a: 10.0,
        max_current_a: 12.0,
    }
}

/// Where a frame number came from.
#[derive(Clone, Copy, Debug)]
struct Origin {
    joint: u8,
    sent_us: u64,
    authentic: bool,
}

/// One real sender (joint 0 or 2).
struct Sender {
    joint: u8,
    session: u16,
    sequence: u16,
    /// Free-running: its clock is (true time - booted_at) * (1 + ppm) + offset.
    booted_at_us: u64,
    clock_offset_us: u32,
    rate_ppm: i64,
    alive: bool,
}

struct Sim {
    mode: Mode,
    node: BusNode,
    comp: Compensator<3, Recorder, NoPredictor>,
    auth: FrameAuth,
    origins: HashMap<u32, Origin>,
    next_frame: u32,
    k: u64,
    senders: [Sender; 2],
    sync_counter: u16,
    sync_session: u16,
    master_alive: bool,
    /// Every SYNC the master sent (a hostile node records them).
    sent_syncs: Vec<CanFdFrame>,
    /// Violations: (tick, joint, why).
    used_bad: Vec<(u64, usize, String)>,
    /// Ticks whose prediction used a state (source Model).
    used_ticks: u64,
    /// True time the free-running offsets were last learned (for the bound).
    learned_at_us: u64,
}

impl Sim {
    fn new(mode: Mode) -> Self {
        let time = match mode {
            Mode::Sync => BusTimeSource::Sync(BusTime::new(BusTimeConfig::every_tick(TICK_US))),
            Mode::FreeRunning => BusTimeSource::FreeRunning,
        };
        let sender = |joint: u8, session: u16, clock_offset_us: u32, rate_ppm: i64| Sender {
            joint,
            session,
            sequence: 0,
            booted_at_us: 0,
            clock_offset_us,
            rate_ppm,
            alive: true,
        };
        Self {
            mode,
            node: BusNode::new(&KEY, time),
            comp: Compensator::new(config(mode), Recorder::default(), NoPredictor).unwrap(),
            auth: FrameAuth::new(&KEY),
            origins: HashMap::new(),
            next_frame: 1,
            k: 0,
            senders: [
                sender(0, 11, 3_000_000_000, 5_000),
                sender(2, 22, 77, -5_000),
            ],
            sync_counter: 0,
            sync_session: 5,
            master_alive: true,
            sent_syncs: Vec::new(),
            used_bad: Vec::new(),
            used_ticks: 0,
            learned_at_us: 0,
        }
    }

    fn true_us(&self) -> u64 {
        self.k * u64::from(TICK_US)
    }

    fn local_us(&self) -> u32 {
        (self.true_us() as u32).wrapping_add(LOCAL_OFFSET_US)
    }

    /// A sender's timestamp now: bus time (SYNC mode) or its own clock.
    fn timestamp(&self, s: &Sender) -> u32 {
        match self.mode {
            Mode::Sync => (self.true_us() as u32).wrapping_add(BUS_OFFSET_US),
            Mode::FreeRunning => {
                let up = (self.true_us() - s.booted_at_us) as i64;
                let t = up + up * s.rate_ppm / 1_000_000;
                (t as u32).wrapping_add(s.clock_offset_us)
            }
        }
    }

    /// A state whose measured position numbers the frame.
    fn numbered_state(&mut self, joint: u8, authentic: bool, q_ref_rad: f32) -> JointState {
        let n = self.next_frame;
        self.next_frame += 1;
        let q_meas = n as f32 * 1e-4;
        self.origins.insert(
            q_meas.to_bits(),
            Origin {
                joint,
                sent_us: self.true_us(),
                authentic,
            },
        );
        JointState::from_array([q_ref_rad, 0.1, 0.0, q_meas, 0.1, 1.0])
    }

    /// The frames the live real senders send this tick.
    fn real_frames(&mut self) -> Vec<CanFdFrame> {
        let mut out = Vec::new();
        for i in 0..2 {
            if !self.senders[i].alive {
                continue;
            }
            let ts = self.timestamp(&self.senders[i]);
            let joint = self.senders[i].joint;
            let state = self.numbered_state(joint, true, 0.5);
            let s = &mut self.senders[i];
            s.sequence = s.sequence.wrapping_add(1);
            let f = StateFrame {
                message: JointStateMessage {
                    joint,
                    session: s.session,
                    sequence: s.sequence,
                    timestamp_us: ts,
                    state,
                },
                faults: FaultFlags::NONE,
                feedforward_nm: 0.0,
            };
            out.push(f.encode(&self.auth).unwrap());
        }
        out
    }

    /// A frame for `joint` as a node without the key makes it: plausible fields, a
    /// continuing sequence and a current timestamp, and a MAC it had to guess.
    fn forged_frame(&mut self, rng: &mut ChaCha8Rng, joint: u8, q_ref_rad: f32) -> CanFdFrame {
        let i = usize::from(joint == 2);
        let ts = self.timestamp(&self.senders[i]);
        let state = self.numbered_state(joint, false, q_ref_rad);
        let s = &self.senders[i];
        let f = StateFrame {
            message: JointStateMessage {
                joint,
                session: s.session,
                sequence: s.sequence.wrapping_add(1),
                timestamp_us: ts,
                state,
            },
            faults: FaultFlags::NONE,
            feedforward_nm: 0.0,
        };
        let mut frame = f.encode(&FrameAuth::new(&rng.r#gen())).unwrap();
        if rng.gen_bool(0.5) {
            // Or random MAC bytes.
            for b in &mut frame.data[STATE_LEN - 8..STATE_LEN] {
                *b = rng.r#gen();
            }
        }
        frame
    }

    /// Reboot a sender: silent from now, back after `gap_us` with a new session,
    /// sequence and (free-running) a clock restarted at zero.
    fn reboot(&mut self, joint: u8) {
        let i = usize::from(joint == 2);
        let now = self.true_us();
        let s = &mut self.senders[i];
        s.alive = false;
        s.session = s.session.wrapping_mul(31).wrapping_add(7);
        s.sequence = 0;
        s.booted_at_us = now;
        s.clock_offset_us = 0;
    }

    /// One tick: SYNC (if the master lives), the delivered frames, the compensator
    /// tick; then every state the prediction read is checked.
    fn step(&mut self, delivered: &[CanFdFrame]) -> CompensatorOutput {
        self.k += 1;
        let local = self.local_us();
        if self.mode == Mode::Sync && self.master_alive {
            self.sync_counter = self.sync_counter.wrapping_add(1);
            let sync = SyncFrame {
                session: self.sync_session,
                counter: self.sync_counter,
                bus_time_us: (self.true_us() as u32).wrapping_add(BUS_OFFSET_US),
            }
            .encode(&self.auth);
            self.sent_syncs.push(sync);
            self.node.receive(&sync, local, &mut self.comp);
        }
        for f in delivered {
            self.node.receive(f, local, &mut self.comp);
        }
        let own = JointState::from_array([1.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        let out = self.node.tick(&mut self.comp, &own, local);
        if let Some(seen) = self.comp.model_mut().seen.take() {
            self.used_ticks += 1;
            self.check(&seen);
        }
        out
    }

    /// The bound on a used state's true age: the compensator's age bound and one
    /// tick, plus (free-running) what the offset may follow at the rate tolerance
    /// since it was learned.
    fn bound_us(&self) -> u64 {
        let base = u64::from(MAX_AGE_US + TICK_US);
        match self.mode {
            Mode::Sync => base,
            Mode::FreeRunning => {
                let since = self.true_us() - self.learned_at_us;
                base + since * u64::from(RATE_PPM) / 1_000_000
            }
        }
    }

    fn check(&mut self, seen: &[JointState; 3]) {
        let now = self.true_us();
        let bound = self.bound_us();
        for j in [0usize, 2] {
            let why = match self.origins.get(&seen[j].q_meas_rad.to_bits()) {
                None => Some("a state no frame carried".to_string()),
                Some(o) if !o.authentic => Some("an unauthenticated frame".to_string()),
                Some(o) if usize::from(o.joint) != j => Some("another joint's frame".to_string()),
                Some(o) if now - o.sent_us > bound => Some(format!(
                    "a frame {} us old (bound {bound})",
                    now - o.sent_us
                )),
                Some(_) => None,
            };
            if let Some(why) = why {
                self.used_bad.push((self.k, j, why));
            }
        }
    }

    /// Run `n` clean ticks (every real frame delivered at once).
    fn run_clean(&mut self, n: u64) -> CompensatorOutput {
        let mut out = CompensatorOutput::default();
        for _ in 0..n {
            let f = self.real_frames();
            out = self.step(&f);
        }
        out
    }

    fn assert_clean(&self, what: &str) {
        assert!(
            self.used_bad.is_empty(),
            "{:?} {what}: {} ticks used a bad state, first {:?}",
            self.mode,
            self.used_bad.len(),
            self.used_bad.first()
        );
    }
}

/// A settled run (the feedforward from the model, no fault).
fn settled(mode: Mode) -> Sim {
    let mut sim = Sim::new(mode);
    let out = sim.run_clean(100);
    assert_eq!(out.source, FeedforwardSource::Model, "{mode:?}: {out:?}");
    assert!(out.faults.is_empty(), "{mode:?}: {out:?}");
    sim
}

#[test]
fn clean_bus_runs_the_model_in_both_modes() {
    for mode in MODES {
        let mut sim = settled(mode);
        let out = sim.run_clean(500);
        assert_eq!((out.source, out.torque_nm), (FeedforwardSource::Model, 3.0));
        assert_eq!(sim.used_ticks, 600, "{mode:?}");
        sim.assert_clean("clean");
    }
}

#[test]
fn replay_across_a_reboot_is_never_used() {
    for mode in MODES {
        for gap_us in [100_000u64, 1_000_000] {
            for newest_first in [false, true] {
                let mut sim = settled(mode);
                // A hostile node records two seconds of joint 0's frames and SYNC.
                let mut recorded = Vec::new();
                for _ in 0..200 {
                    let f = sim.real_frames();
                    recorded.push(f[0]);
                    sim.step(&f);
                }
                let syncs = sim.sent_syncs.clone();
                // Joint 0 reboots; during its boot gap the recording is replayed,
                // one frame (and, on the SYNC bus, one old SYNC) per tick.
                sim.reboot(0);
                let gap_ticks = gap_us / u64::from(TICK_US);
                let mut ff_max = 0.0f32;
                for i in 0..gap_ticks as usize {
                    let idx = if newest_first {
                        recorded.len() - 1 - i % recorded.len()
                    } else {
                        i % recorded.len()
                    };
                    let mut f = sim.real_frames();
                    f.push(recorded[idx]);
                    if mode == Mode::Sync {
                        f.push(syncs[idx % syncs.len()]);
                    }
                    let out = sim.step(&f);
                    ff_max = ff_max.max(out.torque_nm.abs());
                    if i > 4 {
                        assert_eq!(out.source, FeedforwardSource::Zero, "{mode:?} gap {i}");
                    }
                }
                sim.assert_clean(&format!("replay, gap {gap_us} us"));
                assert!(ff_max <= 3.0, "{mode:?}: feedforward {ff_max} N*m");
                // The sender is back with a new session: the model runs again.
                sim.senders[0].alive = true;
                let out = sim.run_clean(50);
                assert_eq!(out.source, FeedforwardSource::Model, "{mode:?}: {out:?}");
                sim.assert_clean("after the reboot");
            }
        }
    }
}

#[test]
fn old_frames_replayed_beside_a_live_sender_do_not_even_pause_the_sync_bus() {
    let mut sim = settled(Mode::Sync);
    let mut recorded = Vec::new();
    for _ in 0..50 {
        let f = sim.real_frames();
        recorded.push(f[0]);
        sim.step(&f);
    }
    sim.run_clean(10);
    // Frames from 10 to 60 ticks ago, one per tick, before the real ones.
    for (i, old) in recorded.iter().enumerate() {
        let mut f = vec![*old];
        f.extend(sim.real_frames());
        let out = sim.step(&f);
        assert_eq!(out.source, FeedforwardSource::Model, "{i}: {out:?}");
        assert_eq!(out.faults, FaultFlags::STATE_REJECTED, "{i}: {out:?}");
    }
    sim.assert_clean("replay beside a live sender");
}

#[test]
fn a_delay_growing_5_ms_per_tick_is_never_used() {
    for mode in MODES {
        let mut sim = settled(mode);
        let mut sent: Vec<(u64, CanFdFrame)> = Vec::new();
        let mut next = 0usize;
        let mut stale = 0;
        let ticks = 400u64;
        for i in 1..=ticks {
            let f = sim.real_frames();
            sent.push((sim.true_us() + u64::from(TICK_US), f[0]));
            // Joint 0's frames are held back by 5 ms more every tick.
            let release = sim.true_us() + u64::from(TICK_US) - 5_000 * i;
            let mut deliver = vec![f[1]];
            while next < sent.len() && sent[next].0 <= release {
                deliver.push(sent[next].1);
                next += 1;
            }
            let out = sim.step(&deliver);
            stale += u32::from(out.faults.contains(FaultFlags::STATE_STALE));
        }
        sim.assert_clean("growing delay");
        // Stale from the moment the delay passes the bound on.
        assert!(
            stale as u64 >= ticks - 12,
            "{mode:?}: stale on {stale} ticks"
        );
        // The delay removed: the model runs again.
        let out = sim.run_clean(30);
        assert_eq!(out.source, FeedforwardSource::Model, "{mode:?}: {out:?}");
    }
}

#[test]
fn a_silenced_and_replaced_sender_is_never_used_and_is_flagged() {
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    for mode in MODES {
        let mut sim = settled(mode);
        sim.senders[0].alive = false;
        for i in 0..300 {
            let mut f = sim.real_frames();
            // The impostor's state would push the feedforward to the limit.
            let forged = sim.forged_frame(&mut rng, 0, 6.5);
            f.push(forged);
            let out = sim.step(&f);
            assert!(
                out.faults.contains(FaultFlags::FRAME_UNAUTHENTICATED),
                "{mode:?} {i}"
            );
            if i >= 3 {
                assert!(
                    out.faults
                        .contains(FaultFlags::SENDER_SILENT | FaultFlags::STATE_STALE),
                    "{mode:?} {i}: {out:?}"
                );
                assert_eq!(out.source, FeedforwardSource::Zero, "{mode:?} {i}");
            }
            assert!(out.torque_nm.abs() <= 3.0, "{mode:?} {i}: {out:?}");
        }
        assert_eq!(sim.comp.unauthenticated_frames(), 300);
        sim.assert_clean("replaced sender");
    }
}

#[test]
fn one_forged_frame_changes_nothing_but_the_flag() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for mode in MODES {
        let mut clean = settled(mode);
        let mut attacked = settled(mode);
        for i in 0..50 {
            let f = clean.real_frames();
            let a = clean.step(&f);
            let mut g = attacked.real_frames();
            if i == 10 {
                // Before the real frame, a continuing sequence number, a 20 N*m step.
                g.insert(0, attacked.forged_frame(&mut rng, 0, 6.5));
            }
            let b = attacked.step(&g);
            assert_eq!(a.torque_nm.to_bits(), b.torque_nm.to_bits(), "{mode:?} {i}");
            assert_eq!(a.source, b.source);
            assert_eq!(
                b.faults,
                if i == 10 {
                    a.faults | FaultFlags::FRAME_UNAUTHENTICATED
                } else {
                    a.faults
                },
                "{mode:?} {i}"
            );
        }
        assert_eq!(attacked.comp.unauthenticated_frames(), 1);
        attacked.assert_clean("one forged frame");
    }
}

#[test]
fn random_corruption_and_garbage_are_never_used() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for mode in MODES {
        let mut sim = settled(mode);
        let mut injected = 0u32;
        for i in 0..2000u32 {
            let mut f = sim.real_frames();
            let real = f[0];
            // 1 to 4 flipped bits anywhere in the payload, or a garbage payload of
            // the state frame's length; sometimes the real frame is lost.
            let mut bad = real;
            if i % 5 == 0 {
                for b in &mut bad.data[..STATE_LEN] {
                    *b = rng.r#gen();
                }
            } else {
                let bits = 1 + (i % 4) as usize;
                let mut flipped = Vec::new();
                while flipped.len() < bits {
                    let b = rng.gen_range(0..STATE_LEN * 8);
                    if !flipped.contains(&b) {
                        flipped.push(b);
                        bad.data[b / 8] ^= 1 << (b % 8);
                    }
                }
            }
            if rng.gen_bool(0.5) {
                f[0] = bad;
            } else {
                f.push(bad);
            }
            injected += 1;
            sim.step(&f);
        }
        assert_eq!(sim.comp.unauthenticated_frames(), injected, "{mode:?}");
        sim.assert_clean("corruption");
        assert!(sim.used_ticks > 500, "{mode:?}: {}", sim.used_ticks);
    }
}

#[test]
fn four_bit_errors_never_authenticate() {
    // 200 000 random 4-bit corruptions of state frames: none decodes.
    let auth = FrameAuth::new(&KEY);
    let mut rng = ChaCha8Rng::seed_from_u64(200_000);
    let mut accepted = 0;
    for n in 0..200_000u32 {
        let f = StateFrame {
            message: JointStateMessage {
                joint: (n % 6) as u8,
                session: 3,
                sequence: n as u16,
                timestamp_us: n.wrapping_mul(1000),
                state: JointState::from_array([0.5, 0.1, 0.0, 0.2, 0.1, 1.0]),
            },
            faults: FaultFlags::NONE,
            feedforward_nm: 1.0,
        };
        let mut frame = f.encode(&auth).unwrap();
        let mut flipped = [usize::MAX; 4];
        let mut k = 0;
        while k < 4 {
            let b = rng.gen_range(0..STATE_LEN * 8);
            if !flipped.contains(&b) {
                flipped[k] = b;
                k += 1;
                frame.data[b / 8] ^= 1 << (b % 8);
            }
        }
        accepted += u32::from(StateFrame::decode(&auth, &frame).is_ok());
    }
    assert_eq!(accepted, 0);
}

#[test]
fn a_silent_master_stops_the_feedforward_and_old_syncs_do_not_restart_it() {
    let mut sim = settled(Mode::Sync);
    let syncs = sim.sent_syncs.clone();
    sim.master_alive = false;
    for i in 0..50 {
        let out = sim.run_clean(1);
        if i >= 3 {
            assert_eq!(out.source, FeedforwardSource::Zero, "{i}: {out:?}");
            assert!(out.faults.contains(FaultFlags::STATE_STALE));
        }
    }
    // The master back: the model runs again.
    sim.master_alive = true;
    let out = sim.run_clean(30);
    assert_eq!(out.source, FeedforwardSource::Model, "{out:?}");
    // Replayed SYNC while the master lives: refused, the bus time is kept.
    let before = sim.node.bus_time().unwrap().conflicts();
    for s in syncs.iter().take(20) {
        let f = sim.real_frames();
        let mut d = vec![*s];
        d.extend(f);
        let out = sim.step(&d);
        assert_eq!(out.source, FeedforwardSource::Model, "{out:?}");
    }
    assert_eq!(sim.node.bus_time().unwrap().conflicts(), before + 20);
    sim.assert_clean("SYNC replay");
}

#[test]
fn bus_load_and_latency_at_the_profile_rate() {
    let rate_hz = firmware::model::default::CONTROL_RATE_HZ as f32;
    let mut lines = String::new();
    for (joints, hz) in [(6u32, rate_hz), (6, 1000.0)] {
        let b = BusBudget::of(joints, hz, BitRates::MOTEUS);
        lines += &format!(
            "CAN-FD 1/5 Mbit/s, {joints} joints + SYNC at {hz} Hz: load {:.1} %, worst-case latency {:.1} us (tick {:.0} us)\n",
            100.0 * b.load,
            b.worst_latency_us,
            b.tick_period_us
        );
    }
    print!("{lines}");
    // The board README holds these lines as printed here.
    let readme = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../board/README.md"),
    )
    .unwrap();
    let want = format!("<!-- canfd-budget -->\n{lines}<!-- /canfd-budget -->");
    assert!(
        readme.contains(&want),
        "board/README.md should hold:\n{want}"
    );
    let b = BusBudget::of(6, rate_hz, BitRates::MOTEUS);
    assert!(
        b.load < 0.5 && b.worst_latency_us < b.tick_period_us,
        "{b:?}"
    );
}
