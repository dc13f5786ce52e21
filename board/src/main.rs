//! Board binary for the joint-drive MCU (STM32G474RE, Cortex-M4F, 170 MHz).
//!
//! Wires the library's control loop to the peripherals (the `board` crate's modules,
//! register level on the `stm32g4` PAC):
//! - `config_block` + `firmware::control::startup`: which joint this board drives,
//!   from its configuration page; the joint's `JointProfile` from the compiled-in
//!   model (`JOINT_PROFILES`) gives the drive and the compensator their settings. A
//!   refused block: no feedforward, no state frames, the fault reported every second.
//! - `pwm` (TIM1, 20 kHz, complementary outputs with dead time) triggers `adc` (three
//!   injected conversions); the ADC's end-of-sequence interrupt (`ADC1_2`) is the
//!   PWM-rate control interrupt: it reads the encoder (`encoder_spi`, AS5047P through
//!   `firmware::drivers::as5047p`), runs `JointDrive::pwm_tick` and writes the three
//!   compare values.
//! - `state_bus` (USART3): `JointStateMessage` frames (37 bytes, CRC-16) to and from
//!   the other joints, standing in for EtherCAT, with a `session` number drawn from
//!   the RNG at every start.
//! - `tick` (SysTick at the model's control rate): the compensator tick, run in
//!   thread mode so the LSTM's time never delays the PWM interrupt, and its DWT
//!   CYCCNT measurement.
//! - defmt over RTT (`--features defmt`): cycles (DWT CYCCNT, measured on the
//!   hardware) of the PWM tick and the compensator tick, faults, feedforward.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(unsafe_code)]

/// Built for the host: nothing to run.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the board binary runs on the STM32G474 only: `cargo board-build`");
    std::process::exit(2);
}

#[cfg(target_os = "none")]
mod app {
    use board::adc::{AMPS_PER_COUNT, Adc, CURRENT_ZERO_COUNTS, VOLTS_PER_COUNT};
    use board::boards::generic::BOARD;
    use board::encoder_spi::EncoderSpi;
    use board::pac::{self, interrupt};
    use board::pwm::Pwm;
    use board::state_bus::Bus;
    use board::{ccm, clock, config_block, pins, pwm, session, state_bus, tick};
    use core::cell::RefCell;
    use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
    use cortex_m::interrupt::Mutex;
    use cortex_m_rt::{ExceptionFrame, entry, exception};
    use firmware::control::{
        BusClock, Compensator, FaultFlags, FrameReceiver, JointDrive, JointProfile, JointReference,
        JointState, JointStateMessage, LstmPredictor, SensorSample, SubsetModel, plan_startup,
    };
    use firmware::drivers::as5047p::{As5047p, counts_to_rad};
    use firmware::dynamics::RigidBodyModel;
    use firmware::model::default as compiled;
    use heapless::Deque;
    #[cfg(not(feature = "defmt"))]
    use panic_halt as _;
    #[cfg(feature = "defmt")]
    use {defmt_rtt as _, panic_probe as _};

    /// Core clock: HSI16 through the PLL (boost mode).
    const CORE_CLOCK_HZ: u32 = clock::CORE_CLOCK_HZ;
    /// Control tick rate (SysTick): the compensator tick, at the rate the compiled-in
    /// network was trained for.
    const TICK_HZ: u32 = compiled::CONTROL_RATE_HZ;
    /// PWM frequency, Hz.
    const PWM_HZ: u32 = 20_000;
    /// TIM1 auto-reload for center-aligned PWM at `PWM_HZ`.
    const PWM_ARR: u16 = pwm::auto_reload(CORE_CLOCK_HZ, PWM_HZ);
    /// Compensated joints of the compiled-in model (the wrist: joints 4, 5, 6); which
    /// of them this board drives is read from its configuration block at start-up.
    const JOINTS: usize = compiled::JOINT_INDICES.len();
    /// The compensator tick's period, microseconds.
    const TICK_PERIOD_US: u32 = 1_000_000 / TICK_HZ;
    // Every compensated joint's sender-timestamp check is on: a few ticks, against
    // each sender's clock (the UART has no distributed clock).
    const _: () = {
        let mut k = 0;
        while k < JOINTS {
            let c = compiled::JOINT_PROFILES[k].compensator_config(TICK_HZ, k);
            assert!(
                c.max_message_age_us <= 5 * TICK_PERIOD_US
                    && matches!(c.bus_clock, BusClock::FreeRunning { .. })
            );
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

    /// What the PWM interrupt owns.
    struct PwmContext {
        drive: JointDrive,
        encoder: As5047p<EncoderSpi>,
        pwm: Pwm,
        adc: Adc,
    }

    static PWM_CONTEXT: Mutex<RefCell<Option<PwmContext>>> = Mutex::new(RefCell::new(None));
    /// Bus frames received by the USART interrupt, drained by the compensator tick.
    static RX_MESSAGES: Mutex<RefCell<Deque<JointStateMessage, 8>>> =
        Mutex::new(RefCell::new(Deque::new()));
    static RX_FRAMES: Mutex<RefCell<FrameReceiver>> =
        Mutex::new(RefCell::new(FrameReceiver::new()));
    /// Feedforward current (f32 bits), written by the compensator, held by the PWM tick.
    static FEEDFORWARD_A: AtomicU32 = AtomicU32::new(0);
    /// The PWM tick's latest joint state (f32 bits) for the compensator and the bus.
    static OWN_Q_RAD: AtomicU32 = AtomicU32::new(0);
    static OWN_QD_RAD_S: AtomicU32 = AtomicU32::new(0);
    static OWN_IQ_A: AtomicU32 = AtomicU32::new(0);
    /// Faults of the PWM ticks since the last report.
    static PWM_FAULTS: AtomicU32 = AtomicU32::new(0);
    /// Longest PWM tick since the last report, cycles (DWT CYCCNT).
    static PWM_TICK_MAX_CYCLES: AtomicU32 = AtomicU32::new(0);
    /// Set by SysTick: a compensator tick is due.
    static COMPENSATOR_DUE: AtomicBool = AtomicBool::new(false);

    #[entry]
    fn main() -> ! {
        ccm::copy_code();
        let (Some(mut cp), Some(dp)) = (cortex_m::Peripherals::take(), pac::Peripherals::take())
        else {
            cortex_m::asm::udf();
        };
        tick::enable_cycle_counter(&mut cp.DCB, &mut cp.DWT);
        // Which joint: the configuration page against the compiled-in model's joints.
        let plan = plan_startup(
            &config_block::read(),
            &compiled::JOINT_INDICES,
            &compiled::JOINT_PROFILES,
            PWM_HZ as f32,
            TICK_HZ,
        );
        let joint = plan.joint.ok();
        let bus_baud = joint
            .and_then(|j| compiled::JOINT_PROFILES.get(j.slot))
            .map_or(JointProfile::BOARD.bus_baud, |p| p.bus_baud);

        // 170 MHz: boost mode, 4 flash wait states, HSI16 / 4 * 85 / 2.
        let _ = clock::boost_170_mhz(&dp.RCC, &dp.PWR, &dp.FLASH);
        if !clock::flash_single_bank(&dp.FLASH) {
            firmware::fw_warn!(
                "flash in dual-bank mode (DBANK = 1): weights read from flash take twice the budgeted wait; provision DBANK = 0"
            );
        }
        let session = session::draw(&dp.RCC, &dp.RNG);
        pins::init(&dp.RCC, &BOARD);
        let mut pwm = Pwm::init(&dp.RCC, dp.TIM1, PWM_ARR);
        let mut adc = Adc::init(&dp.RCC, &dp.ADC12_COMMON, dp.ADC1);
        let Some(encoder_cs) = BOARD.by_role("encoder chip select") else {
            cortex_m::asm::udf();
        };
        let encoder_spi = EncoderSpi::init(&dp.RCC, dp.SPI1, encoder_cs.pin);
        let mut bus = Bus::init(&dp.RCC, dp.USART3, CORE_CLOCK_HZ, bus_baud);

        // The drive: the joint's profile (on a refused block, the drive all compensated
        // joints share, if they do; else the bridge stays off: no PWM interrupt).
        if let Some(config) = plan.drive {
            let mut drive = JointDrive::new(config);
            drive.set_position_origin(0.0);
            // Hold the start position until a trajectory master sends references.
            drive.set_reference(&JointReference::default());
            adc.start();
            pwm.start();
            cortex_m::interrupt::free(|cs| {
                if let Ok(mut slot) = PWM_CONTEXT.borrow(cs).try_borrow_mut() {
                    *slot = Some(PwmContext {
                        drive,
                        encoder: As5047p::new(encoder_spi),
                        pwm,
                        adc,
                    });
                }
            });
        }
        // The LSTM stage: the compiled-in network in its preset's feature layout (with
        // the `drive` preset's linear stage); the compensator only for a configured joint.
        let Some(lstm) = LstmPredictor::<_, JOINTS, { compiled::INPUTS }>::new(
            &compiled::NETWORK,
            compiled::FEATURE_PRESET,
        ) else {
            cortex_m::asm::udf();
        };
        let lstm = lstm
            .with_linear_stage(compiled::LINEAR_STAGE)
            .with_envelope(compiled::ENVELOPE);
        let mut compensator = match plan.compensator {
            Some(config) => match Compensator::<JOINTS, _, _>::new(config, model(), lstm) {
                Ok(c) => Some(
                    c.with_adaptation(plan.adaptation)
                        .with_monitor(plan.monitor),
                ),
                Err(_) => cortex_m::asm::udf(),
            },
            None => None,
        };
        start_interrupts(&mut cp.NVIC, plan.drive.is_some());
        tick::start_systick(&mut cp.SYST, CORE_CLOCK_HZ, TICK_HZ);
        match plan.joint {
            Ok(_j) => firmware::fw_info!(
                "board up as joint {=u8} (slot {=usize}): tick {=u32} Hz, PWM {=u32} Hz",
                _j.joint_number,
                _j.slot,
                TICK_HZ,
                PWM_HZ
            ),
            Err(_fault) => firmware::fw_error!(
                "board up WITHOUT a joint ({}): feedforward off, no state frames, bridge {=str}",
                _fault,
                if plan.drive.is_some() { "on" } else { "off" }
            ),
        }
        let drive_gain_nm_per_a = plan.compensator.map_or(0.0, |c| c.drive_gain_nm_per_a);

        let mut ticks: u32 = 0;
        let mut sequence: u16 = 0;
        let mut comp_cycles = firmware::log::TickStats::new();
        let mut comp_faults = FaultFlags::NONE;
        loop {
            if !COMPENSATOR_DUE.swap(false, Ordering::Acquire) {
                cortex_m::asm::wfi();
                continue;
            }
            let start = tick::cycles();
            ticks = ticks.wrapping_add(1);
            let now_us = ticks.wrapping_mul(TICK_PERIOD_US);
            // Drain the bus (bounded by the queue's capacity).
            for _ in 0..8 {
                let Some(m) = cortex_m::interrupt::free(|cs| {
                    RX_MESSAGES.borrow(cs).try_borrow_mut().ok()?.pop_front()
                }) else {
                    break;
                };
                if let Some(c) = compensator.as_mut() {
                    c.receive(&m);
                }
            }
            let load = |a: &AtomicU32| f32::from_bits(a.load(Ordering::Relaxed));
            let own = JointState {
                q_ref_rad: 0.0,
                qd_ref_rad_s: 0.0,
                qdd_ref_rad_s2: 0.0,
                q_meas_rad: load(&OWN_Q_RAD),
                qd_meas_rad_s: load(&OWN_QD_RAD_S),
                tau_meas_nm: load(&OWN_IQ_A) * drive_gain_nm_per_a,
            };
            let (Some(c), Some(j)) = (compensator.as_mut(), joint) else {
                // No configured joint: feedforward stays zero; say why once a second.
                if ticks.is_multiple_of(TICK_HZ) {
                    firmware::fw_error!(
                        "tick {=u32}: no joint configuration ({}): feedforward off; faults pwm {=u32:#06x}",
                        ticks,
                        plan.joint.err(),
                        PWM_FAULTS.swap(0, Ordering::Relaxed)
                    );
                }
                continue;
            };
            let out = c.tick(&own, now_us);
            FEEDFORWARD_A.store(out.current_a.to_bits(), Ordering::Relaxed);
            // Tell the other joints our state.
            sequence = sequence.wrapping_add(1);
            let frame = JointStateMessage {
                joint: j.slot as u8,
                session,
                sequence,
                timestamp_us: now_us,
                state: own,
            }
            .encode();
            bus.send(&frame);
            let cycles = tick::cycles().wrapping_sub(start);
            comp_cycles.record(cycles);
            comp_faults |= out.faults;
            if ticks.is_multiple_of(TICK_HZ) {
                let pwm_cycles = PWM_TICK_MAX_CYCLES.swap(0, Ordering::Relaxed);
                let pwm_faults = PWM_FAULTS.swap(0, Ordering::Relaxed);
                let comp = comp_cycles.take();
                firmware::fw_info!(
                    "tick {=u32}: PWM tick max {=u32} cycles; compensator tick min/mean/max {=u32}/{=u32}/{=u32} cycles (DWT CYCCNT, measured); faults pwm {=u32:#06x} comp {=u32:#010x}; ff {=f32} A",
                    ticks,
                    pwm_cycles,
                    comp.min_cycles,
                    comp.mean_cycles(),
                    comp.max_cycles,
                    pwm_faults,
                    comp_faults.bits(),
                    out.current_a
                );
                let _ = (pwm_cycles, pwm_faults, comp);
                comp_faults = FaultFlags::NONE;
            }
        }
    }

    /// Unmasks the state bus's interrupt and, when the drive runs, the PWM-rate
    /// control interrupt (priorities: PWM above the bus).
    #[allow(unsafe_code)]
    fn start_interrupts(nvic: &mut cortex_m::peripheral::NVIC, drive: bool) {
        // SAFETY: unmasking handlers that exist in this binary, after everything they
        // reach (PWM_CONTEXT, the frame queue) was set up; no critical section is
        // open here.
        unsafe {
            nvic.set_priority(pac::Interrupt::ADC1_2, 0x10);
            nvic.set_priority(pac::Interrupt::USART3, 0x40);
            if drive {
                cortex_m::peripheral::NVIC::unmask(pac::Interrupt::ADC1_2);
            }
            cortex_m::peripheral::NVIC::unmask(pac::Interrupt::USART3);
        }
    }

    /// The compensator tick's clock (its DWT CYCCNT measurement is in `main`).
    #[exception]
    fn SysTick() {
        COMPENSATOR_DUE.store(true, Ordering::Release);
    }

    /// The PWM-rate control interrupt: ADC1 injected end of sequence (TIM1-triggered).
    /// Runs from CCM SRAM (the section `ccm::copy_code` fills before interrupts are
    /// enabled).
    #[interrupt]
    #[allow(unsafe_code)]
    #[unsafe(link_section = ".ccmram_text")]
    fn ADC1_2() {
        static mut CONTEXT: Option<PwmContext> = None;
        let start = tick::cycles();
        if CONTEXT.is_none() {
            *CONTEXT = cortex_m::interrupt::free(|cs| {
                PWM_CONTEXT.borrow(cs).try_borrow_mut().ok()?.take()
            });
        }
        let Some(ctx) = CONTEXT.as_mut() else {
            return;
        };
        let raw = ctx.adc.read_injected_and_clear();
        let angle = match ctx.encoder.read_angle_counts() {
            Ok(c) => counts_to_rad(c),
            Err(_) => f32::NAN, // the drive flags SENSOR_INVALID and opens the bridge
        };
        let sample = SensorSample {
            phase_current_a: [
                (raw[0] as f32 - CURRENT_ZERO_COUNTS) * AMPS_PER_COUNT,
                (raw[1] as f32 - CURRENT_ZERO_COUNTS) * AMPS_PER_COUNT,
            ],
            motor_angle_rad: angle,
            bus_v: raw[2] as f32 * VOLTS_PER_COUNT,
        };
        ctx.drive
            .set_feedforward_current(f32::from_bits(FEEDFORWARD_A.load(Ordering::Relaxed)));
        let out = ctx.drive.pwm_tick(&sample);
        ctx.pwm.set_duties(out.duties, out.bridge_enabled);
        OWN_Q_RAD.store(out.q_rad.to_bits(), Ordering::Relaxed);
        OWN_QD_RAD_S.store(out.qd_rad_s.to_bits(), Ordering::Relaxed);
        OWN_IQ_A.store(out.iq_meas_a.to_bits(), Ordering::Relaxed);
        PWM_FAULTS.fetch_or(out.faults.bits(), Ordering::Relaxed);
        let cycles = tick::cycles().wrapping_sub(start);
        PWM_TICK_MAX_CYCLES.fetch_max(cycles, Ordering::Relaxed);
    }

    /// State-bus reception: bytes into frames into the queue (bounded per interrupt).
    #[interrupt]
    fn USART3() {
        for _ in 0..8 {
            let Some(byte) = state_bus::read_byte() else {
                break;
            };
            cortex_m::interrupt::free(|cs| {
                let (Ok(mut rx), Ok(mut q)) = (
                    RX_FRAMES.borrow(cs).try_borrow_mut(),
                    RX_MESSAGES.borrow(cs).try_borrow_mut(),
                ) else {
                    return;
                };
                if let Some(m) = rx.push(byte) {
                    if q.is_full() {
                        let _ = q.pop_front();
                    }
                    let _ = q.push_back(m);
                }
            });
        }
    }

    /// Park the drive: the bridge outputs follow TIM1's break/idle state.
    #[allow(unsafe_code)] // cortex-m-rt requires the handler to be `unsafe fn`
    #[exception]
    unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
        firmware::fw_error!("HardFault: pc={=u32:#x}", _frame.pc());
        loop {
            cortex_m::asm::bkpt();
        }
    }
}
