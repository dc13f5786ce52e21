//! The moteus r4.11 image (`cargo board-build` builds it beside `board`): the pin
//! map `board::boards::moteus_r4_11`, the 170 MHz clock, the DRV8353 gate driver's
//! safe start-up over SPI1 (chip select PC4: enable, write and read back every
//! control register, read both status registers), then ENABLE low again; then the
//! joint on the CAN-FD state bus: its configuration block (which joint, the bus
//! key), the compensator of that joint's profile, and FDCAN1 (`board::fdcan`)
//! carrying authenticated state frames and SYNC (`firmware::control::canfd`). Every
//! compensator tick (SysTick at the model's rate) it reads the on-board AS5047P
//! (chip select PB11) for its own joint state, takes the frames received since the
//! last tick (SYNC to the bus time, every joint's state to the compensator, each
//! checked for MAC, session, sequence and age), runs the compensator and broadcasts
//! its own state frame with its fault flags and feedforward. The drive whose joint
//! is the model's first compensated joint (slot 0) is the SYNC master. The bridge
//! is never switched: the PWM timer (TIM5) and the three-ADC current sampling are
//! not wired yet (board README, "moteus r4.11"), so the feedforward is computed,
//! broadcast and logged, not applied, and the measured torque in the state frame is
//! zero.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(unsafe_code)]

/// Built for the host: nothing to run.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("board-moteus runs on the moteus r4.11 only: `cargo board-build`");
    std::process::exit(2);
}

#[cfg(target_os = "none")]
mod app {
    use board::boards::moteus_r4_11::{BOARD, GATE_DRIVER};
    use board::encoder_spi::EncoderSpi;
    use board::fdcan::{self, Can};
    use board::pac::{self, interrupt};
    use board::pins::{self, Output};
    use board::tick::MicrosClock;
    use board::{ccm, clock, config_block, session, tick};
    use core::cell::RefCell;
    use core::f32::consts::{PI, TAU};
    use core::sync::atomic::{AtomicBool, Ordering};
    use cortex_m::interrupt::Mutex;
    use cortex_m_rt::{ExceptionFrame, entry, exception};
    use firmware::control::canfd::{
        BusNode, BusTime, BusTimeConfig, BusTimeSource, CanFdFrame, StateFrame, SyncFrame,
    };
    use firmware::control::{
        BusClock, Compensator, FaultFlags, JointState, JointStateMessage, LstmPredictor,
        SubsetModel, plan_startup,
    };
    use firmware::drivers::as5047p::{As5047p, counts_to_rad};
    use firmware::drivers::drv83x3::{Drv83x3, Variant};
    use firmware::dynamics::RigidBodyModel;
    use firmware::model::default as compiled;
    use heapless::Deque;
    #[cfg(not(feature = "defmt"))]
    use panic_halt as _;
    #[cfg(feature = "defmt")]
    use {defmt_rtt as _, panic_probe as _};

    /// Compensator tick rate (SysTick): the compiled-in network's control rate.
    const TICK_HZ: u32 = compiled::CONTROL_RATE_HZ;
    /// The compensator tick's period, microseconds.
    const TICK_PERIOD_US: u32 = 1_000_000 / TICK_HZ;
    /// PWM rate the drive configuration is planned at (the drive is not run here).
    const PWM_HZ: f32 = 20_000.0;
    /// Compensated joints of the compiled-in model.
    const JOINTS: usize = compiled::JOINT_INDICES.len();
    /// Received frames held between two ticks (a 6-joint robot sends 6 + SYNC).
    const RX_CAPACITY: usize = 16;
    // Every compensated joint's message age is a few ticks.
    const _: () = {
        let mut k = 0;
        while k < JOINTS {
            let c = compiled::JOINT_PROFILES[k].compensator_config(TICK_HZ, k);
            assert!(c.max_message_age_us <= 5 * TICK_PERIOD_US);
            k += 1;
        }
    };

    /// Index in the compiled-in dynamics of each compensated joint.
    const MODEL_JOINTS: [usize; JOINTS] =
        firmware::model::dynamics_indices(compiled::JOINT_INDICES, compiled::DYNAMICS_JOINTS);

    fn model() -> SubsetModel<
        &'static RigidBodyModel<{ compiled::DYNAMICS_JOINTS }>,
        { compiled::DYNAMICS_JOINTS },
        JOINTS,
    > {
        SubsetModel {
            model: &compiled::DYNAMICS,
            joints: MODEL_JOINTS,
            fixed_q_rad: [0.0; compiled::DYNAMICS_JOINTS],
        }
    }

    /// Frames received by the FDCAN1 interrupt with their DWT cycle count, drained by
    /// the compensator tick.
    static RX_FRAMES: Mutex<RefCell<Deque<(CanFdFrame, u32), RX_CAPACITY>>> =
        Mutex::new(RefCell::new(Deque::new()));
    /// Set by SysTick: a compensator tick is due.
    static COMPENSATOR_DUE: AtomicBool = AtomicBool::new(false);

    /// The role's pin, or a HardFault at start-up (the map is checked on the host,
    /// `board/tests/pin_map.rs`, so this never happens with the committed map).
    fn pin(role: &str) -> board::boards::PinId {
        match BOARD.by_role(role) {
            Some(a) => a.pin,
            None => cortex_m::asm::udf(),
        }
    }

    /// The motor angle unwrapped across turns and the joint state it gives.
    struct OwnJoint {
        gear_ratio: f32,
        last_motor_rad: Option<f32>,
        motor_turns_rad: f32,
        q_rad: f32,
    }

    impl OwnJoint {
        /// The joint state after an encoder reading (`None`: a failed read, the
        /// state is not finite and the compensator refuses it).
        fn update(&mut self, motor_rad: Option<f32>) -> JointState {
            let mut state = JointState::default();
            let Some(angle) = motor_rad else {
                self.last_motor_rad = None;
                state.q_meas_rad = f32::NAN;
                return state;
            };
            let step = match self.last_motor_rad {
                Some(last) => {
                    let d = angle - last;
                    if d > PI {
                        d - TAU
                    } else if d < -PI {
                        d + TAU
                    } else {
                        d
                    }
                }
                None => 0.0,
            };
            self.last_motor_rad = Some(angle);
            self.motor_turns_rad += step;
            let q = self.motor_turns_rad / self.gear_ratio;
            state.qd_meas_rad_s = (q - self.q_rad) * TICK_HZ as f32;
            state.q_meas_rad = q;
            self.q_rad = q;
            state
        }
    }

    #[entry]
    fn main() -> ! {
        ccm::copy_code();
        let (Some(mut cp), Some(dp)) = (cortex_m::Peripherals::take(), pac::Peripherals::take())
        else {
            cortex_m::asm::udf();
        };
        tick::enable_cycle_counter(&mut cp.DCB, &mut cp.DWT);
        if !clock::boost_170_mhz(&dp.RCC, &dp.PWR, &dp.FLASH) {
            firmware::fw_warn!("the 170 MHz clock set-up timed out");
        }
        // Every pin of the map; the gate driver's ENABLE and HIZ start low.
        pins::init(&dp.RCC, &BOARD);
        let enable = Output(pin("gate driver enable"));
        let _fault_line = pin("gate driver nFAULT");

        let spi = EncoderSpi::init(&dp.RCC, dp.SPI1, pin("gate driver chip select"));
        let mut drv = Drv83x3::new(spi, enable, Variant::Drv8353);
        // t_WAKE of the DRV8353 is at most 1 ms; wait 2 ms.
        let started = drv.start_up(&GATE_DRIVER, || {
            cortex_m::asm::delay(2 * clock::CORE_CLOCK_HZ / 1000)
        });
        if let Ok(_f) = started {
            firmware::fw_info!(
                "gate driver up: configuration read back, status {=u16:#x} {=u16:#x}, nFAULT {=bool}",
                _f.status1,
                _f.status2,
                pins::read(_fault_line)
            );
        } else {
            firmware::fw_error!(
                "gate driver start-up refused (no answer, a register read back wrong, or a fault): ENABLE low"
            );
        }
        // Bridge off: nothing in this image switches the gates.
        let _ = drv.disable();
        let (spi, _) = drv.release();
        let spi = EncoderSpi::init(&dp.RCC, spi.release(), pin("encoder chip select"));
        let mut encoder = As5047p::new(spi);

        // Which joint, and the bus key: the configuration block.
        let plan = plan_startup(
            &config_block::read(),
            &compiled::JOINT_INDICES,
            &compiled::JOINT_PROFILES,
            PWM_HZ,
            TICK_HZ,
        );
        let (Ok(joint), Some(config)) = (plan.joint, plan.compensator) else {
            // No joint: no compensator, no state frames; say why once a second.
            loop {
                firmware::fw_error!(
                    "no joint configuration ({}): no state frames; provision this drive",
                    plan.joint.err()
                );
                cortex_m::asm::delay(clock::CORE_CLOCK_HZ);
            }
        };
        let Some(lstm) = LstmPredictor::<_, JOINTS, { compiled::INPUTS }>::new(
            &compiled::NETWORK,
            compiled::FEATURE_PRESET,
        ) else {
            cortex_m::asm::udf();
        };
        let lstm = lstm
            .with_linear_stage(compiled::LINEAR_STAGE)
            .with_envelope(compiled::ENVELOPE);
        let Ok(compensator) = Compensator::<JOINTS, _, _>::new(config, model(), lstm) else {
            cortex_m::asm::udf();
        };
        let mut compensator = compensator
            .with_adaptation(plan.adaptation)
            .with_monitor(plan.monitor);
        // The bus time: the SYNC master's (the profile's default), or free-running.
        let time = match config.bus_clock {
            BusClock::Synchronised => {
                BusTimeSource::Sync(BusTime::new(BusTimeConfig::every_tick(TICK_PERIOD_US)))
            }
            BusClock::FreeRunning { .. } => BusTimeSource::FreeRunning,
        };
        let sync_master = joint.slot == 0 && matches!(time, BusTimeSource::Sync(_));
        let mut node = BusNode::new(&joint.bus_key, time);
        let session = session::draw(&dp.RCC, &dp.RNG);
        let mut can = match Can::init(&dp.RCC, dp.FDCAN1) {
            Ok(c) => c,
            Err(_e) => loop {
                firmware::fw_error!("FDCAN1 did not start ({}): no state bus", _e);
                cortex_m::asm::delay(clock::CORE_CLOCK_HZ);
            },
        };
        let mut own_joint = OwnJoint {
            gear_ratio: compiled::JOINT_PROFILES
                .get(joint.slot)
                .map_or(1.0, |p| p.gear_ratio),
            last_motor_rad: None,
            motor_turns_rad: 0.0,
            q_rad: 0.0,
        };
        start_interrupts(&mut cp.NVIC);
        tick::start_systick(&mut cp.SYST, clock::CORE_CLOCK_HZ, TICK_HZ);
        firmware::fw_info!(
            "moteus up as joint {=u8} (slot {=usize}) on CAN-FD: tick {=u32} Hz, {=str}",
            joint.joint_number,
            joint.slot,
            TICK_HZ,
            if sync_master {
                "SYNC master"
            } else if matches!(config.bus_clock, BusClock::Synchronised) {
                "following SYNC"
            } else {
                "free-running bus clock"
            }
        );

        let mut clock = MicrosClock::new(clock::CORE_CLOCK_HZ);
        let mut ticks: u32 = 0;
        let mut sequence: u16 = 0;
        let mut sync_counter: u16 = 0;
        let mut faults = FaultFlags::NONE;
        let mut comp_cycles = firmware::log::TickStats::new();
        loop {
            if !COMPENSATOR_DUE.swap(false, Ordering::Acquire) {
                cortex_m::asm::wfi();
                continue;
            }
            let start = tick::cycles();
            ticks = ticks.wrapping_add(1);
            let local_us = clock.now_us();
            if sync_master {
                sync_counter = sync_counter.wrapping_add(1);
                let sync = SyncFrame {
                    session,
                    counter: sync_counter,
                    bus_time_us: local_us,
                }
                .encode(node.auth());
                can.send(&sync);
                // The master follows its own SYNC like every other node.
                faults |= node.receive(&sync, local_us, &mut compensator);
            }
            // The frames received since the last tick (bounded by the queue).
            for _ in 0..RX_CAPACITY {
                let Some((frame, at)) = cortex_m::interrupt::free(|cs| {
                    RX_FRAMES.borrow(cs).try_borrow_mut().ok()?.pop_front()
                }) else {
                    break;
                };
                let rx_us = clock.at(at);
                faults |= node.receive(&frame, rx_us, &mut compensator);
            }
            let local_us = clock.now_us();
            let angle = encoder.read_angle_counts().ok().map(counts_to_rad);
            let own = own_joint.update(angle);
            let out = node.tick(&mut compensator, &own, local_us);
            faults |= out.faults;
            // Our state on the bus, stamped with the bus time (none without SYNC).
            if let Some(bus_us) = node.now_us(local_us) {
                sequence = sequence.wrapping_add(1);
                let frame = StateFrame {
                    message: JointStateMessage {
                        joint: joint.slot as u8,
                        session,
                        sequence,
                        timestamp_us: bus_us,
                        state: own,
                    },
                    faults: out.faults,
                    feedforward_nm: out.torque_nm,
                }
                .encode(node.auth());
                if let Some(f) = frame {
                    can.send(&f);
                }
            }
            comp_cycles.record(tick::cycles().wrapping_sub(start));
            if ticks.is_multiple_of(TICK_HZ) {
                let _comp = comp_cycles.take();
                let (_tec, _rec) = can.error_counters();
                firmware::fw_info!(
                    "tick {=u32}: q {=f32} rad, ff {=f32} N*m (not applied), faults {=u32:#010x}; tick min/mean/max {=u32}/{=u32}/{=u32} cycles; unauthenticated {=u32}, SYNC refused {=u32}, tx dropped {=u32}, TEC/REC {=u8}/{=u8}",
                    ticks,
                    own.q_meas_rad,
                    out.torque_nm,
                    faults.bits(),
                    _comp.min_cycles,
                    _comp.mean_cycles(),
                    _comp.max_cycles,
                    compensator.unauthenticated_frames(),
                    node.bus_time().map_or(0, |t| t.conflicts()),
                    can.dropped(),
                    _tec,
                    _rec
                );
                faults = FaultFlags::NONE;
            }
        }
    }

    /// Unmasks FDCAN1 interrupt 0 (Rx FIFO 0), after the frame queue exists.
    #[allow(unsafe_code)]
    fn start_interrupts(nvic: &mut cortex_m::peripheral::NVIC) {
        // SAFETY: unmasking a handler of this binary after the queue it fills was
        // set up; no critical section is open here.
        unsafe {
            nvic.set_priority(pac::Interrupt::FDCAN1_IT0, 0x40);
            cortex_m::peripheral::NVIC::unmask(pac::Interrupt::FDCAN1_IT0);
        }
    }

    /// The compensator tick's clock.
    #[exception]
    fn SysTick() {
        COMPENSATOR_DUE.store(true, Ordering::Release);
    }

    /// CAN-FD reception: every frame of Rx FIFO 0 (three at most) into the queue with
    /// its arrival cycle count; a full queue drops its oldest frame.
    #[interrupt]
    fn FDCAN1_IT0() {
        for _ in 0..4 {
            let Some(frame) = fdcan::receive() else {
                break;
            };
            let at = tick::cycles();
            cortex_m::interrupt::free(|cs| {
                let Ok(mut q) = RX_FRAMES.borrow(cs).try_borrow_mut() else {
                    return;
                };
                if q.is_full() {
                    let _ = q.pop_front();
                }
                let _ = q.push_back((frame, at));
            });
        }
    }

    /// A HardFault stops here (halts the core; a debugger shows where). ENABLE is
    /// low then unless the fault hit between `start_up` and `disable`; the PWM inputs
    /// stay low (TIM5 is never started), so no gate is switched either way.
    #[allow(unsafe_code)] // cortex-m-rt requires the handler to be `unsafe fn`
    #[exception]
    unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
        loop {
            cortex_m::asm::bkpt();
        }
    }
}
