//! TI DRV8323S / DRV8353S three-phase gate driver over SPI, generic over an
//! embedded-hal 1.0 [`SpiDevice`] (mode 1, MSB first, chip select low per frame) and an
//! [`OutputPin`] on its ENABLE input.
//!
//! Frames are 16 bits: bit 15 R/W (1 = read), bits 14..11 the address, bits 10..0 the
//! data; the device answers in the same frame (bits 10..0: the addressed register).
//! Register map (datasheets SLVSDJ3 section 8.6 and SLVSDY6 section 8.6): 0x00 fault
//! status 1, 0x01 VGS status 2, 0x02 driver control, 0x03 gate drive HS, 0x04 gate
//! drive LS, 0x05 OCP control, 0x06 CSA control, 0x07 driver configuration (DRV8353
//! only: CAL_MODE; reserved on the DRV8323).
//!
//! Safe start-up ([`Drv83x3::start_up`]): enable, write every control register, read
//! each back, read both status registers; any SPI error, read-back mismatch or fault
//! bit drives ENABLE low (every gate off) and is returned, so the caller keeps the
//! bridge off, as the safety chain does for every other fault.

use embedded_hal::digital::OutputPin;
use embedded_hal::spi::SpiDevice;

/// Register addresses (4 bits).
pub mod addr {
    /// Fault status 1 (read only).
    pub const FAULT_STATUS_1: u8 = 0x00;
    /// VGS status 2 (read only).
    pub const VGS_STATUS_2: u8 = 0x01;
    /// Driver control.
    pub const DRIVER_CONTROL: u8 = 0x02;
    /// Gate drive high side.
    pub const GATE_DRIVE_HS: u8 = 0x03;
    /// Gate drive low side.
    pub const GATE_DRIVE_LS: u8 = 0x04;
    /// Overcurrent protection control.
    pub const OCP_CONTROL: u8 = 0x05;
    /// Current-sense amplifier control.
    pub const CSA_CONTROL: u8 = 0x06;
    /// Driver configuration (DRV8353: CAL_MODE in bit 0).
    pub const DRIVER_CONFIG: u8 = 0x07;
}

/// The 11 data bits of a frame.
pub const DATA_MASK: u16 = 0x07FF;

/// The frame that reads a register.
#[inline]
pub const fn read_frame(address: u8) -> u16 {
    0x8000 | (((address & 0x0F) as u16) << 11)
}

/// The frame that writes `data` (11 bits) to a register.
#[inline]
pub const fn write_frame(address: u8, data: u16) -> u16 {
    (((address & 0x0F) as u16) << 11) | (data & DATA_MASK)
}

/// Which device of the family: the register map differs in two places.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Variant {
    /// DRV8323S (60 V): driver control bit 10 reserved, no register 0x07.
    Drv8323,
    /// DRV8353S (100 V): driver control bit 10 is OCP_ACT, register 0x07 CAL_MODE.
    Drv8353,
}

/// PWM input mode (driver control bits 6..5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PwmMode {
    /// Six inputs, one per gate.
    SixInput = 0,
    /// Three inputs (INHx), the device makes the complementary low side and dead time.
    ThreeInput = 1,
    /// One PWM input with hall-state commutation.
    OneInput = 2,
    /// Independent half-bridge control.
    Independent = 3,
}

/// What an overcurrent does (OCP control bits 7..6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OcpMode {
    /// Latched shutdown until cleared.
    LatchedFault = 0,
    /// Automatic retry after TRETRY.
    AutomaticRetry = 1,
    /// Report only.
    ReportOnly = 2,
    /// No report, no action.
    Ignored = 3,
}

/// Driver control register (0x02).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriverControl {
    /// Bit 10, DRV8353 OCP_ACT: an overcurrent shuts all three half-bridges down.
    pub ocp_act: bool,
    /// Bit 9: charge-pump undervoltage fault disabled.
    pub dis_cpuv: bool,
    /// Bit 8: gate drive fault disabled.
    pub dis_gdf: bool,
    /// Bit 7: overtemperature warning reported on nFAULT.
    pub otw_rep: bool,
    /// Bits 6..5.
    pub pwm_mode: PwmMode,
    /// Bit 4: 1x PWM asynchronous rectification.
    pub pwm1_com: bool,
    /// Bit 3: 1x PWM direction.
    pub pwm1_dir: bool,
    /// Bit 2: every MOSFET off (coast).
    pub coast: bool,
    /// Bit 1: every low side on (brake).
    pub brake: bool,
    /// Bit 0: clear the latched faults (self-clearing).
    pub clr_flt: bool,
}

impl DriverControl {
    /// The 11 data bits.
    pub const fn encode(&self) -> u16 {
        (self.ocp_act as u16) << 10
            | (self.dis_cpuv as u16) << 9
            | (self.dis_gdf as u16) << 8
            | (self.otw_rep as u16) << 7
            | (self.pwm_mode as u16) << 5
            | (self.pwm1_com as u16) << 4
            | (self.pwm1_dir as u16) << 3
            | (self.coast as u16) << 2
            | (self.brake as u16) << 1
            | (self.clr_flt as u16)
    }

    /// From the 11 data bits.
    pub const fn decode(d: u16) -> Self {
        Self {
            ocp_act: d & (1 << 10) != 0,
            dis_cpuv: d & (1 << 9) != 0,
            dis_gdf: d & (1 << 8) != 0,
            otw_rep: d & (1 << 7) != 0,
            pwm_mode: match (d >> 5) & 3 {
                0 => PwmMode::SixInput,
                1 => PwmMode::ThreeInput,
                2 => PwmMode::OneInput,
                _ => PwmMode::Independent,
            },
            pwm1_com: d & (1 << 4) != 0,
            pwm1_dir: d & (1 << 3) != 0,
            coast: d & (1 << 2) != 0,
            brake: d & (1 << 1) != 0,
            clr_flt: d & 1 != 0,
        }
    }
}

/// A 4-bit register field code (gate currents, VDS level): the current or voltage
/// each code means is the datasheet's table for the variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Code4(u8);

impl Code4 {
    /// A code, `None` above 15.
    pub const fn new(code: u8) -> Option<Self> {
        if code < 16 { Some(Self(code)) } else { None }
    }
    /// The code.
    pub const fn get(self) -> u8 {
        self.0
    }
    /// The smallest code whose table value reaches `value` (the last code when none does).
    pub const fn at_least(table: &[u16; 16], value: u16) -> Self {
        let mut i = 0;
        while i < 15 && table[i] < value {
            i += 1;
        }
        Self(i as u8)
    }
}

/// Gate-current tables, mA, per code: (source, sink) per variant (SLVSDJ3 table
/// "IDRIVEP/IDRIVEN", SLVSDY6 same).
pub mod idrive_ma {
    /// DRV8323 IDRIVEP (source), mA.
    pub const DRV8323_SOURCE: [u16; 16] = [
        10, 30, 60, 80, 120, 140, 170, 190, 260, 330, 370, 440, 570, 680, 820, 1000,
    ];
    /// DRV8323 IDRIVEN (sink), mA.
    pub const DRV8323_SINK: [u16; 16] = [
        20, 60, 120, 160, 240, 280, 340, 380, 520, 660, 740, 880, 1140, 1360, 1640, 2000,
    ];
    /// DRV8353 IDRIVEP (source), mA (codes 0 and 1 both 50 mA).
    pub const DRV8353_SOURCE: [u16; 16] = [
        50, 50, 100, 150, 300, 350, 400, 450, 550, 600, 650, 700, 850, 900, 950, 1000,
    ];
    /// DRV8353 IDRIVEN (sink), mA (codes 0 and 1 both 100 mA).
    pub const DRV8353_SINK: [u16; 16] = [
        100, 100, 200, 300, 600, 700, 800, 900, 1100, 1200, 1300, 1400, 1700, 1800, 1900, 2000,
    ];
}

/// VDS overcurrent thresholds, mV, per VDS_LVL code (SLVSDJ3 / SLVSDY6 OCP control).
pub mod vds_lvl_mv {
    /// DRV8323.
    pub const DRV8323: [u16; 16] = [
        60, 130, 200, 260, 310, 450, 530, 600, 680, 750, 940, 1130, 1300, 1500, 1700, 1880,
    ];
    /// DRV8353.
    pub const DRV8353: [u16; 16] = [
        60, 70, 80, 90, 100, 200, 300, 400, 500, 600, 700, 800, 900, 1000, 1500, 2000,
    ];
}

/// Gate drive HS register (0x03); LOCK is always written as unlocked (0b011).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GateDriveHs {
    /// Bits 7..4: high-side source current code.
    pub idrivep: Code4,
    /// Bits 3..0: high-side sink current code.
    pub idriven: Code4,
}

/// LOCK field value that unlocks the registers (bits 10..8 of 0x03).
pub const LOCK_UNLOCKED: u16 = 0b011;

impl GateDriveHs {
    /// The 11 data bits (LOCK = unlocked).
    pub const fn encode(&self) -> u16 {
        LOCK_UNLOCKED << 8 | (self.idrivep.0 as u16) << 4 | self.idriven.0 as u16
    }
    /// From the 11 data bits (and the LOCK field).
    pub const fn decode(d: u16) -> (Self, u16) {
        (
            Self {
                idrivep: Code4(((d >> 4) & 0xF) as u8),
                idriven: Code4((d & 0xF) as u8),
            },
            (d >> 8) & 7,
        )
    }
}

/// Peak gate-current drive time (gate drive LS bits 9..8).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Tdrive {
    /// 500 ns.
    Ns500 = 0,
    /// 1000 ns.
    Ns1000 = 1,
    /// 2000 ns.
    Ns2000 = 2,
    /// 4000 ns.
    Ns4000 = 3,
}

/// Gate drive LS register (0x04).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GateDriveLs {
    /// Bit 10: cycle-by-cycle overcurrent recovery.
    pub cbc: bool,
    /// Bits 9..8.
    pub tdrive: Tdrive,
    /// Bits 7..4: low-side source current code.
    pub idrivep: Code4,
    /// Bits 3..0: low-side sink current code.
    pub idriven: Code4,
}

impl GateDriveLs {
    /// The 11 data bits.
    pub const fn encode(&self) -> u16 {
        (self.cbc as u16) << 10
            | (self.tdrive as u16) << 8
            | (self.idrivep.0 as u16) << 4
            | self.idriven.0 as u16
    }
    /// From the 11 data bits.
    pub const fn decode(d: u16) -> Self {
        Self {
            cbc: d & (1 << 10) != 0,
            tdrive: match (d >> 8) & 3 {
                0 => Tdrive::Ns500,
                1 => Tdrive::Ns1000,
                2 => Tdrive::Ns2000,
                _ => Tdrive::Ns4000,
            },
            idrivep: Code4(((d >> 4) & 0xF) as u8),
            idriven: Code4((d & 0xF) as u8),
        }
    }
}

/// Dead time inserted by the device (OCP control bits 9..8).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DeadTime {
    /// 50 ns.
    Ns50 = 0,
    /// 100 ns.
    Ns100 = 1,
    /// 200 ns.
    Ns200 = 2,
    /// 400 ns.
    Ns400 = 3,
}

/// OCP control register (0x05). The deglitch code's time differs per variant
/// (DRV8323: 2, 4, 6, 8 µs; DRV8353: 1, 2, 4, 8 µs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OcpControl {
    /// Bit 10: retry time 50 µs (else 4 ms; DRV8353: 8 ms).
    pub tretry_short: bool,
    /// Bits 9..8.
    pub dead_time: DeadTime,
    /// Bits 7..6.
    pub ocp_mode: OcpMode,
    /// Bits 5..4: deglitch code (0..3).
    pub ocp_deg: u8,
    /// Bits 3..0: VDS overcurrent threshold code.
    pub vds_lvl: Code4,
}

impl OcpControl {
    /// The 11 data bits.
    pub const fn encode(&self) -> u16 {
        (self.tretry_short as u16) << 10
            | (self.dead_time as u16) << 8
            | (self.ocp_mode as u16) << 6
            | ((self.ocp_deg & 3) as u16) << 4
            | self.vds_lvl.0 as u16
    }
    /// From the 11 data bits.
    pub const fn decode(d: u16) -> Self {
        Self {
            tretry_short: d & (1 << 10) != 0,
            dead_time: match (d >> 8) & 3 {
                0 => DeadTime::Ns50,
                1 => DeadTime::Ns100,
                2 => DeadTime::Ns200,
                _ => DeadTime::Ns400,
            },
            ocp_mode: match (d >> 6) & 3 {
                0 => OcpMode::LatchedFault,
                1 => OcpMode::AutomaticRetry,
                2 => OcpMode::ReportOnly,
                _ => OcpMode::Ignored,
            },
            ocp_deg: ((d >> 4) & 3) as u8,
            vds_lvl: Code4((d & 0xF) as u8),
        }
    }
}

/// Current-sense amplifier gain (CSA control bits 7..6), V/V.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CsaGain {
    /// 5 V/V.
    X5 = 0,
    /// 10 V/V.
    X10 = 1,
    /// 20 V/V.
    X20 = 2,
    /// 40 V/V.
    X40 = 3,
}

impl CsaGain {
    /// The gain, V/V.
    pub const fn v_per_v(self) -> f32 {
        match self {
            CsaGain::X5 => 5.0,
            CsaGain::X10 => 10.0,
            CsaGain::X20 => 20.0,
            CsaGain::X40 => 40.0,
        }
    }
}

/// CSA control register (0x06).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CsaControl {
    /// Bit 10: amplifier positive input on SHx (else SPx).
    pub csa_fet: bool,
    /// Bit 9: reference VREF / 2 (bidirectional sensing).
    pub vref_div: bool,
    /// Bit 8: low-side VDS overcurrent measured SHx to SNx.
    pub ls_ref: bool,
    /// Bits 7..6.
    pub gain: CsaGain,
    /// Bit 5: sense overcurrent fault disabled.
    pub dis_sen: bool,
    /// Bits 4..2: offset calibration of amplifiers A, B, C.
    pub cal: [bool; 3],
    /// Bits 1..0: sense overcurrent level code (0.25, 0.5, 0.75, 1 V).
    pub sen_lvl: u8,
}

impl CsaControl {
    /// The 11 data bits.
    pub const fn encode(&self) -> u16 {
        (self.csa_fet as u16) << 10
            | (self.vref_div as u16) << 9
            | (self.ls_ref as u16) << 8
            | (self.gain as u16) << 6
            | (self.dis_sen as u16) << 5
            | (self.cal[0] as u16) << 4
            | (self.cal[1] as u16) << 3
            | (self.cal[2] as u16) << 2
            | (self.sen_lvl & 3) as u16
    }
    /// From the 11 data bits.
    pub const fn decode(d: u16) -> Self {
        Self {
            csa_fet: d & (1 << 10) != 0,
            vref_div: d & (1 << 9) != 0,
            ls_ref: d & (1 << 8) != 0,
            gain: match (d >> 6) & 3 {
                0 => CsaGain::X5,
                1 => CsaGain::X10,
                2 => CsaGain::X20,
                _ => CsaGain::X40,
            },
            dis_sen: d & (1 << 5) != 0,
            cal: [d & (1 << 4) != 0, d & (1 << 3) != 0, d & (1 << 2) != 0],
            sen_lvl: (d & 3) as u8,
        }
    }
}

/// Fault status 1 (0x00) and VGS status 2 (0x01), as read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Faults {
    /// Fault status 1's 11 bits: 10 FAULT, 9 VDS_OCP, 8 GDF, 7 UVLO, 6 OTSD,
    /// 5..0 VDS_HA, VDS_LA, VDS_HB, VDS_LB, VDS_HC, VDS_LC.
    pub status1: u16,
    /// VGS status 2's 11 bits: 10..8 SA_OC, SB_OC, SC_OC, 7 OTW, 6 CPUV,
    /// 5..0 VGS_HA, VGS_LA, VGS_HB, VGS_LB, VGS_HC, VGS_LC.
    pub status2: u16,
}

impl Faults {
    /// Status 1: any fault (the device's own summary bit).
    pub const FAULT: u16 = 1 << 10;
    /// Status 1: VDS monitor overcurrent.
    pub const VDS_OCP: u16 = 1 << 9;
    /// Status 1: gate drive fault.
    pub const GDF: u16 = 1 << 8;
    /// Status 1: supply undervoltage lockout.
    pub const UVLO: u16 = 1 << 7;
    /// Status 1: overtemperature shutdown.
    pub const OTSD: u16 = 1 << 6;
    /// Status 2: sense-amplifier overcurrent, phases A, B, C.
    pub const SX_OC: u16 = 0b111 << 8;
    /// Status 2: overtemperature warning (a warning, not a shutdown).
    pub const OTW: u16 = 1 << 7;
    /// Status 2: charge-pump undervoltage.
    pub const CPUV: u16 = 1 << 6;

    /// True when a bit that stops the bridge is set (every bit but the
    /// overtemperature warning).
    pub const fn any(&self) -> bool {
        self.status1 & DATA_MASK != 0 || self.status2 & DATA_MASK & !Self::OTW != 0
    }
}

/// The configuration written at start-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Register 0x02 (CLR_FLT is sent once at start-up whatever this says; OCP_ACT
    /// is forced off on the DRV8323, where the bit is reserved).
    pub driver_control: DriverControl,
    /// Register 0x03.
    pub gate_drive_hs: GateDriveHs,
    /// Register 0x04.
    pub gate_drive_ls: GateDriveLs,
    /// Register 0x05.
    pub ocp_control: OcpControl,
    /// Register 0x06.
    pub csa_control: CsaControl,
}

impl Config {
    /// The data bits each register 0x02..=0x07 must hold afterwards, in address order
    /// (register 0x07: CAL_MODE = 1 on the DRV8353, which makes its amplifier
    /// calibration behave as the DRV8323's; 0 on the DRV8323).
    pub const fn register_values(&self, variant: Variant) -> [u16; 6] {
        let is_8353 = matches!(variant, Variant::Drv8353);
        let mut dc = self.driver_control;
        dc.clr_flt = false;
        if !is_8353 {
            dc.ocp_act = false;
        }
        [
            dc.encode(),
            self.gate_drive_hs.encode(),
            self.gate_drive_ls.encode(),
            self.ocp_control.encode(),
            self.csa_control.encode(),
            is_8353 as u16,
        ]
    }
}

/// Driver errors. Every one leaves ENABLE low (gates off) when returned by
/// [`Drv83x3::start_up`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<S, P> {
    /// The SPI bus failed.
    Spi(S),
    /// The ENABLE pin failed.
    Pin(P),
    /// A register read back other than written (no device, a stuck bus, a lock).
    ReadBack {
        /// The register.
        address: u8,
        /// What was written (11 bits).
        wrote: u16,
        /// What was read (11 bits).
        read: u16,
    },
    /// The device reports a fault.
    Fault(Faults),
}

/// The gate driver: its SPI device, its ENABLE pin and which variant it is.
#[derive(Debug)]
pub struct Drv83x3<SPI, EN> {
    spi: SPI,
    enable: EN,
    variant: Variant,
}

impl<SPI: SpiDevice, EN: OutputPin> Drv83x3<SPI, EN> {
    /// A driver; drives ENABLE low first (gates off). The SPI device must be mode 1.
    pub fn new(spi: SPI, mut enable: EN, variant: Variant) -> Self {
        // A failing pin here is caught again by `start_up`, which drives it first.
        let _ = enable.set_low();
        Self {
            spi,
            enable,
            variant,
        }
    }

    /// Give the SPI device and the pin back.
    pub fn release(self) -> (SPI, EN) {
        (self.spi, self.enable)
    }

    /// The variant.
    pub fn variant(&self) -> Variant {
        self.variant
    }

    fn frame(&mut self, out: u16) -> Result<u16, Error<SPI::Error, EN::Error>> {
        let mut buf = out.to_be_bytes();
        self.spi.transfer_in_place(&mut buf).map_err(Error::Spi)?;
        Ok(u16::from_be_bytes(buf) & DATA_MASK)
    }

    /// Read a register's 11 data bits.
    pub fn read(&mut self, address: u8) -> Result<u16, Error<SPI::Error, EN::Error>> {
        self.frame(read_frame(address))
    }

    /// Write a register's 11 data bits.
    pub fn write(&mut self, address: u8, data: u16) -> Result<(), Error<SPI::Error, EN::Error>> {
        self.frame(write_frame(address, data)).map(|_| ())
    }

    /// Read both status registers.
    pub fn read_faults(&mut self) -> Result<Faults, Error<SPI::Error, EN::Error>> {
        Ok(Faults {
            status1: self.read(addr::FAULT_STATUS_1)?,
            status2: self.read(addr::VGS_STATUS_2)?,
        })
    }

    /// ENABLE low: every gate off (the device's registers return to their defaults).
    pub fn disable(&mut self) -> Result<(), Error<SPI::Error, EN::Error>> {
        self.enable.set_low().map_err(Error::Pin)
    }

    /// Safe start-up: ENABLE high, then (after the device's wake-up time, which the
    /// caller waits between `enable` and this call's register writes by passing
    /// `wait_wake`, at least 1 ms) clear latched faults, write registers 0x02..=0x07,
    /// read each back and read the status. Any failure drives ENABLE low and is
    /// returned; success leaves the device enabled with its gates following the PWM
    /// inputs. A fixed number of frames: 1 + 6 writes + 6 reads + 2 status reads.
    pub fn start_up(
        &mut self,
        config: &Config,
        wait_wake: impl FnOnce(),
    ) -> Result<Faults, Error<SPI::Error, EN::Error>> {
        self.enable.set_high().map_err(Error::Pin)?;
        wait_wake();
        let r = self.configure(config);
        if r.is_err() {
            let _ = self.enable.set_low();
        }
        r
    }

    fn configure(&mut self, config: &Config) -> Result<Faults, Error<SPI::Error, EN::Error>> {
        let values = config.register_values(self.variant);
        let mut clear = values[0];
        clear |= 1; // CLR_FLT
        self.write(addr::DRIVER_CONTROL, clear)?;
        for (i, v) in values.iter().enumerate() {
            self.write(addr::DRIVER_CONTROL + i as u8, *v)?;
        }
        for (i, v) in values.iter().enumerate() {
            let address = addr::DRIVER_CONTROL + i as u8;
            let read = self.read(address)?;
            if read != *v {
                return Err(Error::ReadBack {
                    address,
                    wrote: *v,
                    read,
                });
            }
        }
        let faults = self.read_faults()?;
        if faults.any() {
            return Err(Error::Fault(faults));
        }
        Ok(faults)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::convert::Infallible;
    use embedded_hal::spi::{ErrorKind, ErrorType, Operation};

    /// Emulates the device: a register file with the datasheet's reset values, read
    /// only status registers, reserved bits that read 0 on the DRV8323, and the answer
    /// in the same frame. Registers read 0 and ignore writes while ENABLE is low.
    struct MockDrv {
        variant: Variant,
        regs: [u16; 8],
        enabled: bool,
        frames: u32,
        fail_bus: bool,
        stuck_miso_high: bool,
        latched: Faults,
        writes: std::vec::Vec<u16>,
    }

    #[derive(Debug, PartialEq, Clone, Copy)]
    struct BusError;
    impl embedded_hal::spi::Error for BusError {
        fn kind(&self) -> ErrorKind {
            ErrorKind::Other
        }
    }
    impl ErrorType for MockDrv {
        type Error = BusError;
    }

    impl MockDrv {
        fn new(variant: Variant) -> Self {
            // DRV8323S reset values (SLVSDJ3 register tables): 0x03 0x3FF, 0x04 0x7FF,
            // 0x05 0x159, 0x06 0x283.
            Self {
                variant,
                regs: [0, 0, 0, 0x3FF, 0x7FF, 0x159, 0x283, 0],
                enabled: true,
                frames: 0,
                fail_bus: false,
                stuck_miso_high: false,
                latched: Faults::default(),
                writes: std::vec::Vec::new(),
            }
        }
        fn exchange(&mut self, frame: u16) -> u16 {
            self.frames += 1;
            if self.stuck_miso_high {
                return 0xFFFF;
            }
            if !self.enabled {
                return 0;
            }
            let a = ((frame >> 11) & 0xF) as usize;
            let d = frame & DATA_MASK;
            if frame & 0x8000 == 0 && a < 8 {
                self.writes.push(frame);
                match a {
                    0 | 1 => {}
                    2 => {
                        if d & 1 != 0 {
                            self.latched = Faults::default();
                        }
                        let mut v = d & !1;
                        if self.variant == Variant::Drv8323 {
                            v &= !(1 << 10);
                        }
                        self.regs[2] = v;
                    }
                    7 => {
                        self.regs[7] = if self.variant == Variant::Drv8353 {
                            d & 1
                        } else {
                            0
                        }
                    }
                    _ => self.regs[a] = d,
                }
            }
            self.regs[0] = self.latched.status1;
            self.regs[1] = self.latched.status2;
            if a < 8 { self.regs[a] } else { 0 }
        }
    }

    impl SpiDevice for MockDrv {
        fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), BusError> {
            if self.fail_bus {
                return Err(BusError);
            }
            for op in ops {
                if let Operation::TransferInPlace(buf) = op {
                    assert_eq!(buf.len(), 2, "16-bit frames");
                    let r = self.exchange(u16::from_be_bytes([buf[0], buf[1]]));
                    buf.copy_from_slice(&r.to_be_bytes());
                } else {
                    panic!("unexpected operation");
                }
            }
            Ok(())
        }
    }

    /// ENABLE pin that records its level and mirrors it into the device.
    struct Pin<'a>(&'a core::cell::Cell<bool>);
    impl embedded_hal::digital::ErrorType for Pin<'_> {
        type Error = Infallible;
    }
    impl OutputPin for Pin<'_> {
        fn set_low(&mut self) -> Result<(), Infallible> {
            self.0.set(false);
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Infallible> {
            self.0.set(true);
            Ok(())
        }
    }

    /// The moteus r4.11 settings (drv8323.h defaults for family 0, hw rev 8).
    fn config() -> Config {
        Config {
            driver_control: DriverControl {
                ocp_act: true,
                dis_cpuv: false,
                dis_gdf: false,
                otw_rep: false,
                pwm_mode: PwmMode::ThreeInput,
                pwm1_com: false,
                pwm1_dir: false,
                coast: false,
                brake: false,
                clr_flt: false,
            },
            gate_drive_hs: GateDriveHs {
                idrivep: Code4::at_least(&idrive_ma::DRV8353_SOURCE, 100),
                idriven: Code4::at_least(&idrive_ma::DRV8353_SINK, 200),
            },
            gate_drive_ls: GateDriveLs {
                cbc: true,
                tdrive: Tdrive::Ns1000,
                idrivep: Code4::at_least(&idrive_ma::DRV8353_SOURCE, 100),
                idriven: Code4::at_least(&idrive_ma::DRV8353_SINK, 600),
            },
            ocp_control: OcpControl {
                tretry_short: false,
                dead_time: DeadTime::Ns50,
                ocp_mode: OcpMode::LatchedFault,
                ocp_deg: 3,
                vds_lvl: Code4::new(10).unwrap(),
            },
            csa_control: CsaControl {
                csa_fet: false,
                vref_div: true,
                ls_ref: false,
                gain: CsaGain::X20,
                dis_sen: false,
                cal: [false; 3],
                sen_lvl: 1,
            },
        }
    }

    #[test]
    fn frame_format_matches_the_datasheet() {
        // R/W in bit 15, address in 14..11, data in 10..0.
        assert_eq!(read_frame(addr::FAULT_STATUS_1), 0x8000);
        assert_eq!(read_frame(addr::VGS_STATUS_2), 0x8800);
        assert_eq!(read_frame(addr::CSA_CONTROL), 0xB000);
        assert_eq!(read_frame(addr::DRIVER_CONFIG), 0xB800);
        assert_eq!(write_frame(addr::DRIVER_CONTROL, 0x0020), 0x1020);
        // Data beyond 11 bits never reaches the address or R/W bits.
        assert_eq!(write_frame(addr::GATE_DRIVE_HS, 0xFFFF), 0x1FFF);
        assert_eq!(write_frame(0x1F, 0), 0x7800);
    }

    #[test]
    fn reset_values_decode_as_the_datasheet_tables() {
        // 0x03 reset 0x3FF: LOCK 011 (unlocked), IDRIVEP_HS 1111, IDRIVEN_HS 1111.
        let (hs, lock) = GateDriveHs::decode(0x3FF);
        assert_eq!(lock, LOCK_UNLOCKED);
        assert_eq!((hs.idrivep.get(), hs.idriven.get()), (15, 15));
        assert_eq!(hs.encode(), 0x3FF);
        // 0x04 reset 0x7FF: CBC 1, TDRIVE 4000 ns, both currents code 15.
        let ls = GateDriveLs::decode(0x7FF);
        assert!(ls.cbc);
        assert_eq!(ls.tdrive, Tdrive::Ns4000);
        assert_eq!(ls.encode(), 0x7FF);
        // 0x05 reset 0x159 (DRV8323): TRETRY 4 ms, dead time 100 ns, automatic
        // retry, deglitch code 1 (4 µs), VDS_LVL code 9 (0.75 V).
        let ocp = OcpControl::decode(0x159);
        assert!(!ocp.tretry_short);
        assert_eq!(ocp.dead_time, DeadTime::Ns100);
        assert_eq!(ocp.ocp_mode, OcpMode::AutomaticRetry);
        assert_eq!(ocp.ocp_deg, 1);
        assert_eq!(ocp.vds_lvl.get(), 9);
        assert_eq!(ocp.encode(), 0x159);
        // 0x06 reset 0x283: VREF_DIV 1, gain 20 V/V, SEN_LVL 1 V.
        let csa = CsaControl::decode(0x283);
        assert!(csa.vref_div && !csa.csa_fet && !csa.ls_ref && !csa.dis_sen);
        assert_eq!(csa.gain, CsaGain::X20);
        assert_eq!(csa.sen_lvl, 3);
        assert_eq!(csa.encode(), 0x283);
        // 0x02 reset 0: six-input PWM, nothing disabled.
        assert_eq!(DriverControl::decode(0).pwm_mode, PwmMode::SixInput);
    }

    #[test]
    fn every_register_round_trips_every_11_bit_value() {
        for d in 0..=DATA_MASK {
            assert_eq!(DriverControl::decode(d).encode(), d);
            assert_eq!(GateDriveLs::decode(d).encode(), d);
            assert_eq!(OcpControl::decode(d).encode(), d);
            assert_eq!(CsaControl::decode(d).encode(), d);
            let (hs, lock) = GateDriveHs::decode(d);
            if lock == LOCK_UNLOCKED {
                assert_eq!(hs.encode(), d);
            }
        }
    }

    #[test]
    fn field_positions_match_the_register_tables() {
        let mut dc = DriverControl::decode(0);
        dc.pwm_mode = PwmMode::ThreeInput;
        assert_eq!(dc.encode(), 0b01 << 5);
        dc.ocp_act = true;
        assert_eq!(dc.encode(), 1 << 10 | 1 << 5);
        let csa = CsaControl {
            gain: CsaGain::X40,
            cal: [true, false, false],
            ..CsaControl::decode(0)
        };
        assert_eq!(csa.encode(), 3 << 6 | 1 << 4);
        assert_eq!(Code4::new(16), None);
        // The gate-current tables: 100 mA source is DRV8353 code 2, 600 mA sink code 4.
        assert_eq!(Code4::at_least(&idrive_ma::DRV8353_SOURCE, 100).get(), 2);
        assert_eq!(Code4::at_least(&idrive_ma::DRV8353_SINK, 600).get(), 4);
        assert_eq!(Code4::at_least(&idrive_ma::DRV8323_SOURCE, 5000).get(), 15);
        assert_eq!(Code4::at_least(&vds_lvl_mv::DRV8353, 700).get(), 10);
        assert_eq!(Code4::at_least(&vds_lvl_mv::DRV8323, 750).get(), 9);
    }

    #[test]
    fn start_up_writes_reads_back_and_enables() {
        for variant in [Variant::Drv8323, Variant::Drv8353] {
            let en = core::cell::Cell::new(true);
            let mut drv = Drv83x3::new(MockDrv::new(variant), Pin(&en), variant);
            assert!(!en.get(), "new() drives ENABLE low");
            let mut woke = false;
            let faults = drv.start_up(&config(), || woke = true).unwrap();
            assert!(woke && en.get());
            assert!(!faults.any());
            let (dev, _) = drv.release();
            assert_eq!(dev.frames, 15);
            // The first write clears latched faults; register 0x02 ends without it.
            assert_eq!(dev.writes[0] & 1, 1);
            let want = config().register_values(variant);
            assert_eq!(&dev.regs[2..8], &want[..]);
            assert_eq!(dev.regs[7], (variant == Variant::Drv8353) as u16);
            assert_eq!(dev.regs[2] >> 10, (variant == Variant::Drv8353) as u16);
        }
    }

    #[test]
    fn any_fault_leaves_the_gates_off() {
        // A fault that CLR_FLT does not clear (it is still present: latch it again).
        struct Sticky(MockDrv, Faults);
        impl ErrorType for Sticky {
            type Error = BusError;
        }
        impl SpiDevice for Sticky {
            fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), BusError> {
                self.0.latched = self.1;
                self.0.transaction(ops)
            }
        }
        for f in [
            Faults {
                status1: Faults::FAULT | Faults::UVLO,
                status2: 0,
            },
            Faults {
                status1: 0,
                status2: Faults::CPUV,
            },
            Faults {
                status1: 0,
                status2: 1 << 8,
            },
        ] {
            let en = core::cell::Cell::new(false);
            let mut drv = Drv83x3::new(
                Sticky(MockDrv::new(Variant::Drv8353), f),
                Pin(&en),
                Variant::Drv8353,
            );
            assert_eq!(drv.start_up(&config(), || {}), Err(Error::Fault(f)));
            assert!(!en.get(), "{f:?} left ENABLE high");
        }
        // An overtemperature warning alone does not stop the bridge.
        assert!(
            !Faults {
                status1: 0,
                status2: Faults::OTW
            }
            .any()
        );
    }

    #[test]
    fn no_device_or_a_dead_bus_leaves_the_gates_off() {
        let en = core::cell::Cell::new(false);
        let mut dev = MockDrv::new(Variant::Drv8323);
        dev.stuck_miso_high = true;
        let mut drv = Drv83x3::new(dev, Pin(&en), Variant::Drv8323);
        assert!(matches!(
            drv.start_up(&config(), || {}),
            Err(Error::ReadBack {
                address: 2,
                read: 0x7FF,
                ..
            })
        ));
        assert!(!en.get());

        let mut dev = MockDrv::new(Variant::Drv8323);
        dev.fail_bus = true;
        let mut drv = Drv83x3::new(dev, Pin(&en), Variant::Drv8323);
        assert_eq!(drv.start_up(&config(), || {}), Err(Error::Spi(BusError)));
        assert!(!en.get());

        // A DRV8323 configured as a DRV8353: register 0x07 reads back 0.
        let mut drv = Drv83x3::new(MockDrv::new(Variant::Drv8323), Pin(&en), Variant::Drv8353);
        assert!(matches!(
            drv.start_up(&config(), || {}),
            Err(Error::ReadBack { address: 2, .. }) | Err(Error::ReadBack { address: 7, .. })
        ));
        assert!(!en.get());
    }

    #[test]
    fn disabled_device_reads_zero_and_faults_read_back() {
        let en = core::cell::Cell::new(false);
        let mut dev = MockDrv::new(Variant::Drv8353);
        dev.latched = Faults {
            status1: Faults::FAULT | Faults::VDS_OCP | 1 << 5,
            status2: Faults::OTW,
        };
        let mut drv = Drv83x3::new(dev, Pin(&en), Variant::Drv8353);
        let f = drv.read_faults().unwrap();
        assert_eq!(f.status1, 0x620);
        assert_eq!(f.status2, Faults::OTW);
        drv.disable().unwrap();
        assert!(!en.get());
        let (mut dev, _) = drv.release();
        dev.enabled = false;
        assert_eq!(dev.exchange(read_frame(addr::CSA_CONTROL)), 0);
    }
}
