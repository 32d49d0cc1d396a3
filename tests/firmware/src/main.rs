//! softfem on a Cortex-M4F: the firmware check.
//!
//! Runs the workload of `scenario.rs` (SVDs of fixed matrices, forces and energies of every
//! model on a small box, explicit, relaxation, Newton and VBD steps of a heapless body dropped
//! on the ground, and softfem's owning `Body` in fixed storage dropped onto a sphere and a
//! capsule) in both precisions on QEMU's `mps2-an386` board, compares every result with
//! the values the host computed from the same source (`$OUT_DIR/expected.rs`, bit for bit),
//! measures instructions and stack, prints a report over semihosting and exits with status 0
//! only if every record matched, no measured call ran the stack down to the end of `.bss` and
//! no fault occurred (a hard fault prints its pc and exits at once).
//!
//! Panic-freedom is checked at link time: the panic handler calls a function that is defined
//! nowhere, so the release build links only if the optimiser removed every panic path from
//! everything this program calls, softfem included. (Debug builds keep panic paths and cannot
//! link: build with `--release`.) Nothing here formats through `core::fmt`, whose float
//! printing keeps panic paths of its own.
//!
//! Instructions are counted with the board's first CMSDK APB timer, a 32-bit down counter on
//! the 25 MHz peripheral clock: QEMU run with `-icount shift=0` advances its virtual clock 1 ns
//! per instruction, so the timer ticks once per 40 instructions. The ratio is calibrated at
//! start-up on a loop of known length. (SysTick, the core's own timer, has 24 bits: it wraps
//! after 671 million instructions, less than one f64 Newton or VBD step.)
#![no_std]
#![no_main]

mod scenario;

use core::arch::asm;
use core::hint::black_box;
use core::panic::PanicInfo;

use cortex_m_rt::{ExceptionFrame, entry, exception};
use cortex_m_semihosting::debug;

use scenario::{Meter, Records, double, single};

// The host's values: `const EXPECTED: &[(&str, u64, u64)]`, one `(name, digest, value bits)` per
// record, in the order the scenario produces them (written by tests/firmware.rs).
include!(concat!(env!("OUT_DIR"), "/expected.rs"));

unsafe extern "C" {
    /// Defined nowhere: a panic path that survives optimisation makes the link fail here.
    fn softfem_firmware_panic_path_survived_optimisation() -> !;
}

#[panic_handler]
fn panic(_info: &PanicInfo) -> ! {
    // SAFETY: never executed: the release build links only if no call to this handler is left.
    unsafe { softfem_firmware_panic_path_survived_optimisation() }
}

// ---------------------------------------------------------------------------------------------
// Output over semihosting, without core::fmt.
// ---------------------------------------------------------------------------------------------

/// One line of the report in a fixed buffer; text past its capacity is dropped and marked.
struct Line {
    buffer: [u8; 200],
    len: usize,
    truncated: bool,
}

impl Line {
    fn new() -> Self {
        Line {
            buffer: [0; 200],
            len: 0,
            truncated: false,
        }
    }

    fn byte(&mut self, byte: u8) -> &mut Self {
        // Two bytes stay free for the newline and the NUL of SYS_WRITE0.
        let room = self.len + 2 < self.buffer.len();
        match self.buffer.get_mut(self.len) {
            Some(slot) if room => {
                *slot = byte;
                self.len += 1;
            }
            _ => self.truncated = true,
        }
        self
    }

    fn str(&mut self, text: &str) -> &mut Self {
        for &byte in text.as_bytes() {
            self.byte(byte);
        }
        self
    }

    fn uint(&mut self, value: u64) -> &mut Self {
        let mut digits = [0u8; 20];
        let mut count = 0;
        let mut rest = value;
        for slot in &mut digits {
            *slot = b'0' + (rest % 10) as u8;
            count += 1;
            rest /= 10;
            if rest == 0 {
                break;
            }
        }
        for &digit in digits.iter().take(count).rev() {
            self.byte(digit);
        }
        self
    }

    fn hex(&mut self, value: u64) -> &mut Self {
        self.str("0x");
        for shift in (0..16).rev() {
            let nibble = ((value >> (4 * shift)) & 15) as u8;
            self.byte(if nibble < 10 {
                b'0' + nibble
            } else {
                b'a' + nibble - 10
            });
        }
        self
    }

    /// `value` with `decimals` digits after the point (display only; rounded half up).
    fn fixed(&mut self, value: u64, scale: u64, decimals: usize) -> &mut Self {
        const POWERS: [u64; 7] = [1, 10, 100, 1_000, 10_000, 100_000, 1_000_000];
        let unit = POWERS.get(decimals).copied().unwrap_or(1);
        let scaled = (u128::from(value) * u128::from(unit) * 2 + u128::from(scale))
            / (2 * u128::from(scale.max(1)));
        let scaled = u64::try_from(scaled).unwrap_or(u64::MAX);
        self.uint(scaled / unit);
        if decimals > 0 {
            self.byte(b'.');
            let fraction = scaled % unit;
            let mut place = unit / 10;
            while place > 0 {
                self.byte(b'0' + ((fraction / place) % 10) as u8);
                place /= 10;
            }
        }
        self
    }

    /// `x` as `d.dddddde±N` (7 significant digits, display only: the checks compare bits).
    fn sci(&mut self, x: f64) -> &mut Self {
        if x.is_nan() {
            return self.str("NaN");
        }
        if x < 0.0 || (x == 0.0 && x.is_sign_negative()) {
            self.byte(b'-');
        }
        let mut magnitude = if x < 0.0 { -x } else { x };
        if magnitude == f64::INFINITY {
            return self.str("inf");
        }
        if magnitude == 0.0 {
            return self.str("0");
        }
        let mut exponent = 0i32;
        while magnitude >= 10.0 {
            magnitude /= 10.0;
            exponent += 1;
        }
        while magnitude < 1.0 {
            magnitude *= 10.0;
            exponent -= 1;
        }
        let mut digits = (magnitude * 1e6 + 0.5) as u64;
        if digits >= 10_000_000 {
            digits /= 10;
            exponent += 1;
        }
        self.fixed(digits, 1_000_000, 6).byte(b'e');
        if exponent < 0 {
            self.byte(b'-');
        }
        self.uint(u64::from(exponent.unsigned_abs()))
    }

    /// Writes the line to the host's standard output and empties it.
    fn emit(&mut self) {
        if self.truncated {
            self.str("~");
        }
        let end = self.len.min(self.buffer.len() - 2);
        if let Some([newline, nul]) = self.buffer.get_mut(end..end + 2) {
            *newline = b'\n';
            *nul = 0;
        }
        // SAFETY: SYS_WRITE0 reads the NUL-terminated string at the pointer, which the buffer
        // holds (the NUL was just written inside it); the host does not write to it.
        unsafe {
            cortex_m_semihosting::syscall1!(WRITE0, self.buffer.as_ptr());
        }
        self.len = 0;
        self.truncated = false;
    }
}

/// Prints `text` as a line of its own.
fn say(text: &str) {
    Line::new().str(text).emit();
}

// ---------------------------------------------------------------------------------------------
// Instruction counting (an APB timer under -icount) and stack high-water marks (painting).
// ---------------------------------------------------------------------------------------------

/// The MPS2 board's APB timer 0 (Arm's CMSDK timer): control, current value and reload
/// registers. It counts down on the 25 MHz peripheral clock and wraps every 2^32 ticks.
const TIMER0_CTRL: *mut u32 = 0x4000_0000 as *mut u32;
const TIMER0_VALUE: *mut u32 = 0x4000_0004 as *mut u32;
const TIMER0_RELOAD: *mut u32 = 0x4000_0008 as *mut u32;

/// Starts timer 0 counting down from its largest value, without interrupts.
fn start_timer() {
    // SAFETY: the timer's registers on this board (mps2-an386 memory map); nothing else uses
    // the timer, and these writes have no effect but to configure it.
    unsafe {
        TIMER0_CTRL.write_volatile(0);
        TIMER0_RELOAD.write_volatile(u32::MAX);
        TIMER0_VALUE.write_volatile(u32::MAX);
        TIMER0_CTRL.write_volatile(1);
    }
}

/// Ticks since the timer started, modulo 2^32 (the timer counts down).
#[inline(always)]
fn ticks() -> u32 {
    // SAFETY: reading the timer's current value has no side effect.
    u32::MAX - unsafe { TIMER0_VALUE.read_volatile() }
}

/// Ticks between two readings, assuming fewer than 2^32 of them (checked by the caller).
#[inline(always)]
fn elapsed(start: u32, end: u32) -> u32 {
    end.wrapping_sub(start)
}

/// The iterations of the calibration loop: two instructions each.
const CALIBRATION_ITERATIONS: u32 = 1_000_000;

/// Runs exactly `2 * iterations` instructions (plus the few that set the loop up).
#[inline(never)]
fn known_instructions(iterations: u32) {
    // SAFETY: a countdown loop on one register; touches no memory and no stack.
    unsafe {
        asm!(
            "2:",
            "subs {n}, #1",
            "bne 2b",
            n = inout(reg) iterations => _,
            options(nomem, nostack),
        );
    }
}

/// The bottom of the stack region, from cortex-m-rt's linker script: the end of `.bss`.
fn stack_floor() -> usize {
    unsafe extern "C" {
        static _stack_end: u32;
    }
    // The address only; the symbol is not read.
    (&raw const _stack_end) as usize
}

#[inline(always)]
fn stack_pointer() -> usize {
    let sp: usize;
    // SAFETY: reads the stack pointer into a register; no memory access.
    unsafe { asm!("mov {}, sp", out(reg) sp, options(nomem, nostack, preserves_flags)) };
    sp
}

/// The word painted below the stack pointer before a measured call, down to the end of `.bss`.
const PAINT: u32 = 0x5afe_c0de;

/// Calls `work` out of line, so that its frame lies below the measuring function's stack pointer.
#[inline(never)]
fn call_out_of_line<R>(work: impl FnOnce() -> R) -> R {
    black_box(work())
}

/// One measured section.
#[derive(Clone, Copy)]
struct Section {
    name: &'static str,
    unit: &'static str,
    calls: u64,
    ticks: u64,
    max_ticks: u32,
    units: u64,
    max_stack: usize,
}

const SECTIONS: usize = 48;

/// The firmware's [`Meter`]: timer ticks and painted-stack high-water marks per section.
struct FirmwareMeter {
    sections: [Section; SECTIONS],
    len: usize,
    /// Instructions and ticks of the calibration loop.
    calibration: (u64, u64),
    /// Ticks of measuring an empty call (subtracted from every call).
    overhead: u32,
    /// Measurements that could not be recorded (table full, call too long).
    lost: u32,
    /// The first section whose call used all the stack down to the end of `.bss`: the stack
    /// may have overwritten statics, and the run fails.
    overflowed: Option<&'static str>,
}

impl FirmwareMeter {
    fn new() -> Self {
        const BLANK: Section = Section {
            name: "",
            unit: "",
            calls: 0,
            ticks: 0,
            max_ticks: 0,
            units: 0,
            max_stack: 0,
        };
        FirmwareMeter {
            sections: [BLANK; SECTIONS],
            len: 0,
            calibration: (1, 1),
            overhead: 0,
            lost: 0,
            overflowed: None,
        }
    }

    fn section(&mut self, name: &'static str) -> Option<&mut Section> {
        let index = self
            .sections
            .iter()
            .take(self.len)
            .position(|s| s.name == name)
            .unwrap_or(self.len);
        let section = self.sections.get_mut(index)?;
        if index == self.len {
            section.name = name;
            self.len += 1;
        }
        Some(section)
    }

    /// Instructions for `ticks` ticks, from the calibration.
    fn instructions(&self, ticks: u64) -> u64 {
        let (instructions, calibration_ticks) = self.calibration;
        ticks.saturating_mul(instructions) / calibration_ticks.max(1)
    }

    /// Measures `work` and returns its ticks (minus the overhead) and stack use in bytes
    /// (`usize::MAX` if it reached the end of `.bss`). The whole free stack is painted, so a
    /// call that overflows it cannot pass unseen.
    #[inline(always)]
    fn run<R>(&self, work: impl FnOnce() -> R) -> (R, u32, usize) {
        let top = stack_pointer() & !3;
        let bottom = stack_floor();
        let words = top.saturating_sub(bottom) / 4;
        let base = bottom as *mut u32;
        for i in 0..words {
            // SAFETY: `[bottom, top)` lies between the end of `.bss` and this function's stack
            // pointer: memory no live object occupies. No interrupt is enabled, and Arm's ABI has
            // no red zone, so nothing else writes below the stack pointer meanwhile.
            unsafe { base.add(i).write_volatile(PAINT) };
        }
        let start = ticks();
        let result = call_out_of_line(work);
        let end = ticks();
        let mut untouched = 0;
        for i in 0..words {
            // SAFETY: as above; the words were painted before the call.
            if unsafe { base.add(i).read_volatile() } != PAINT {
                break;
            }
            untouched += 1;
        }
        let stack = (words - untouched) * 4;
        let spent = elapsed(start, end).saturating_sub(self.overhead);
        (
            result,
            spent,
            if untouched == 0 { usize::MAX } else { stack },
        )
    }

    /// Calibrates ticks against instructions and the cost of measuring nothing.
    fn calibrate(&mut self) {
        let ((), spent, _) = self.run(|| known_instructions(black_box(CALIBRATION_ITERATIONS)));
        self.calibration = (
            2 * u64::from(CALIBRATION_ITERATIONS),
            u64::from(spent.max(1)),
        );
        let ((), empty, _) = self.run(|| ());
        self.overhead = empty;
    }
}

impl Meter for FirmwareMeter {
    fn measure<R>(&mut self, name: &'static str, work: impl FnOnce() -> R) -> R {
        let (result, spent, stack) = self.run(work);
        if stack == usize::MAX && self.overflowed.is_none() {
            self.overflowed = Some(name);
        }
        // A call this long may have wrapped the 32-bit counter more than once.
        let reliable = spent < u32::MAX / 2 && stack != usize::MAX;
        match self.section(name) {
            Some(section) if reliable => {
                section.calls += 1;
                section.ticks += u64::from(spent);
                section.max_ticks = section.max_ticks.max(spent);
                section.max_stack = section.max_stack.max(stack);
            }
            _ => self.lost += 1,
        }
        result
    }

    fn units(&mut self, name: &'static str, unit: &'static str, units: u64) {
        match self.section(name) {
            Some(section) => {
                section.unit = unit;
                section.units += units;
            }
            None => self.lost += 1,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The run.
// ---------------------------------------------------------------------------------------------

static mut BODY_F32: single::DropBody = single::DropBody::EMPTY;
static mut BODY_F64: double::DropBody = double::DropBody::EMPTY;
static mut DESCENT_F32: single::DescentScratch = single::DescentScratch::EMPTY;
static mut DESCENT_F64: double::DescentScratch = double::DescentScratch::EMPTY;
static mut RECORDS: Records = Records::new();
/// softfem's owning bodies of the collider scene: `Body::empty` until built in place
/// (`Body::rebuild_from_box`), in statics because the f64 one is tens of KB.
static mut OWNED_F32: single::ColliderBody = single::COLLIDER_BODY;
static mut OWNED_F64: double::ColliderBody = double::COLLIDER_BODY;

/// Compares the records with [`EXPECTED`], one line each; returns the number of mismatches.
fn compare(records: &Records) -> u64 {
    let mut failed = 0;
    let got = records.as_slice();
    for (index, record) in got.iter().enumerate() {
        let mut line = Line::new();
        match EXPECTED.get(index) {
            Some(&(name, digest, _)) if name == record.name && digest == record.digest => {
                line.str("ok   ")
                    .str(record.name)
                    .str(" = ")
                    .sci(record.value);
            }
            Some(&(name, digest, value)) => {
                failed += 1;
                line.str("FAIL ")
                    .str(record.name)
                    .str(": got ")
                    .hex(record.digest);
                line.str(" (")
                    .sci(record.value)
                    .str("), expected ")
                    .str(name)
                    .str(" ");
                line.hex(digest)
                    .str(" (")
                    .sci(f64::from_bits(value))
                    .str(")");
            }
            None => {
                failed += 1;
                line.str("FAIL ")
                    .str(record.name)
                    .str(": no expected value");
            }
        }
        line.emit();
    }
    if EXPECTED.len() != got.len() || records.overflow > 0 {
        failed += 1;
        let mut line = Line::new();
        line.str("FAIL record count: ")
            .uint(got.len() as u64)
            .str(" produced (");
        line.uint(records.overflow as u64)
            .str(" more did not fit), ");
        line.uint(EXPECTED.len() as u64).str(" expected").emit();
    }
    failed
}

/// Prints every measured section, then the f64/f32 ratios of each pair (per call, and per unit
/// of work).
fn report_measurements(meter: &FirmwareMeter) {
    let sections = meter.sections.get(..meter.len).unwrap_or(&[]);
    for section in sections {
        let instructions = meter.instructions(section.ticks);
        let mut line = Line::new();
        line.str("measure ").str(section.name).str(": ");
        line.uint(section.calls).str(" calls, ");
        line.fixed(instructions, section.calls.max(1), 0)
            .str(" instructions/call");
        if section.units > 0 {
            line.str(", ")
                .fixed(instructions, section.units, 1)
                .str(" per ");
            line.str(section.unit);
        }
        line.str(", max ")
            .uint(meter.instructions(u64::from(section.max_ticks)));
        line.str(", stack ")
            .uint(section.max_stack as u64)
            .str(" B")
            .emit();
    }
    for single in sections {
        let Some(rest) = single.name.strip_prefix("f32 ") else {
            continue;
        };
        let Some(double) = sections
            .iter()
            .find(|s| s.name.strip_prefix("f64 ") == Some(rest))
        else {
            continue;
        };
        let per_call = |s: &Section| meter.instructions(s.ticks) / s.calls.max(1);
        let mut line = Line::new();
        line.str("f64/f32 ").str(rest).str(": ");
        line.fixed(per_call(double), per_call(single), 2)
            .str("x instructions per call, ");
        // Per unit of work where both count the same unit (the solvers' iteration counts
        // differ between the precisions, so per call and per unit differ).
        if single.units > 0 && double.units > 0 && single.unit == double.unit {
            let (d, s) = (
                meter.instructions(double.ticks),
                meter.instructions(single.ticks),
            );
            line.fixed(
                d.saturating_mul(single.units),
                s.saturating_mul(double.units),
                2,
            );
            line.str("x per ").str(single.unit).str(", ");
        }
        line.str("stack ");
        line.uint(single.max_stack as u64).str(" B -> ");
        line.uint(double.max_stack as u64).str(" B").emit();
    }
}

/// Prints the RAM a body needs per vertex and per tetrahedron in precision `Real`.
fn report_ram<Real, Vec3, TetRest>(precision: &str, body_bytes: usize) {
    use core::mem::size_of;
    let vector = size_of::<Vec3>() as u64;
    let scalar = size_of::<Real>() as u64;
    // rest, position, velocity, mass, pinned flag; explicit scratch 4 vectors; relaxation
    // scratch 5 vectors and 1 scalar (see softfem's scratch_len::explicit / scratch_len::relax).
    let state = 3 * vector + scalar + 1;
    let mut line = Line::new();
    line.str("ram ")
        .str(precision)
        .str(": per vertex ")
        .uint(state)
        .str(" B state + ");
    line.uint(4 * vector)
        .str(" B explicit scratch + ")
        .uint(5 * vector + scalar);
    line.str(" B relaxation scratch; per tet ")
        .uint(16 + size_of::<TetRest>() as u64);
    line.str(" B (indices + rest data); drop body ")
        .uint(body_bytes as u64)
        .str(" B")
        .emit();
}

/// Prints the scratch RAM of Newton's method and of Vertex Block Descent per vertex and per
/// tetrahedron, from softfem's length functions (the same in both precisions) and the sizes of
/// the precision's `Vec3`, `Mat3` and `TetHessian`.
fn report_descent_ram<Vec3, Mat3, TetHessian>(precision: &str, descent_bytes: usize) {
    use core::mem::size_of;
    use softfem::step::scratch_len;
    let vector = size_of::<Vec3>() as u64;
    let index = size_of::<u32>() as u64;
    let per_vertex = scratch_len::newton(1, 0);
    let newton_vertex =
        per_vertex.vectors as u64 * vector + per_vertex.blocks as u64 * size_of::<Mat3>() as u64;
    let newton_tet = scratch_len::newton(0, 1).hessians as u64 * size_of::<TetHessian>() as u64;
    let base = scratch_len::vbd_indices(0, 0) as u64;
    let vbd_vertex = scratch_len::vbd(1) as u64 * vector
        + (scratch_len::vbd_indices(1, 0) as u64 - base) * index;
    let vbd_tet = (scratch_len::vbd_indices(0, 1) as u64 - base) * index;
    let mut line = Line::new();
    line.str("ram ")
        .str(precision)
        .str(": Newton scratch ")
        .uint(newton_vertex);
    line.str(" B per vertex + ")
        .uint(newton_tet)
        .str(" B per tet (TetHessian); VBD scratch ");
    line.uint(vbd_vertex)
        .str(" B per vertex + ")
        .uint(vbd_tet)
        .str(" B per tet + ");
    line.uint(base * index)
        .str(" B; drop body's static descent scratch ")
        .uint(descent_bytes as u64)
        .str(" B")
        .emit();
}

/// Prints the size of softfem's owning body of the collider scene (a static here).
fn report_body_ram(precision: &str, bytes: usize, vertices: usize, tets: usize) {
    let mut line = Line::new();
    line.str("ram ")
        .str(precision)
        .str(": softfem::body::Body<FixedStorage<");
    line.uint(vertices as u64)
        .str(", ")
        .uint(tets as u64)
        .str(">, StableNeoHookean> ");
    line.uint(bytes as u64)
        .str(" B (static, every solver's scratch)")
        .emit();
}

/// Measures `libm::sqrtf`, the software square root the f32 math shim used to call.
fn report_libm_sqrt(meter: &mut FirmwareMeter) {
    let mut x = black_box(1.5f32);
    for _ in 0..100 {
        x = meter.measure("libm::sqrtf (software)", || libm::sqrtf(black_box(x)) + 1.0);
    }
    let mut y = black_box(1.5f64);
    for _ in 0..100 {
        y = meter.measure("libm::sqrt (f64, software)", || {
            libm::sqrt(black_box(y)) + 1.0
        });
    }
    black_box((x, y));
}

#[entry]
fn main() -> ! {
    say("softfem firmware check: Cortex-M4F (thumbv7em-none-eabihf) on QEMU mps2-an386");
    start_timer();

    let mut meter = FirmwareMeter::new();
    meter.calibrate();
    let (instructions, calibration_ticks) = meter.calibration;
    let mut line = Line::new();
    line.str("calibration: ")
        .uint(instructions)
        .str(" instructions = ");
    line.uint(calibration_ticks).str(" timer ticks (");
    line.fixed(instructions, calibration_ticks, 2)
        .str(" instructions/tick), overhead ");
    line.uint(u64::from(meter.overhead)).str(" ticks").emit();

    // SAFETY: `main` runs once and never returns, and nothing else refers to these statics:
    // these are their only references. (Through raw pointers, as the 2024 edition requires for
    // `static mut`; hence the lint.)
    #[allow(clippy::deref_addrof)]
    let (records, body32, body64, descent32, descent64, owned32, owned64) = unsafe {
        (
            &mut *(&raw mut RECORDS),
            &mut *(&raw mut BODY_F32),
            &mut *(&raw mut BODY_F64),
            &mut *(&raw mut DESCENT_F32),
            &mut *(&raw mut DESCENT_F64),
            &mut *(&raw mut OWNED_F32),
            &mut *(&raw mut OWNED_F64),
        )
    };
    single::run(&mut meter, records, body32, descent32, owned32);
    double::run(&mut meter, records, body64, descent64, owned64);
    report_libm_sqrt(&mut meter);

    let failed = compare(records);
    report_measurements(&meter);
    report_ram::<f32, softfem::glam::Vec3, softfem::element::TetRest>(
        "f32",
        core::mem::size_of::<single::DropBody>(),
    );
    report_ram::<f64, softfem::glam::DVec3, softfem::f64::element::TetRest>(
        "f64",
        core::mem::size_of::<double::DropBody>(),
    );
    report_descent_ram::<softfem::glam::Vec3, softfem::glam::Mat3, softfem::element::TetHessian>(
        "f32",
        core::mem::size_of::<single::DescentScratch>(),
    );
    report_descent_ram::<
        softfem::glam::DVec3,
        softfem::glam::DMat3,
        softfem::f64::element::TetHessian,
    >("f64", core::mem::size_of::<double::DescentScratch>());
    report_body_ram(
        "f32",
        core::mem::size_of::<single::ColliderBody>(),
        single::COLLIDER_VERTICES,
        single::COLLIDER_TETS,
    );
    report_body_ram(
        "f64",
        core::mem::size_of::<double::ColliderBody>(),
        double::COLLIDER_VERTICES,
        double::COLLIDER_TETS,
    );
    if meter.lost > 0 {
        Line::new()
            .str("note: ")
            .uint(u64::from(meter.lost))
            .str(" measurements lost (table full or call too long)")
            .emit();
    }
    let mut failed = failed;
    if let Some(section) = meter.overflowed {
        failed += 1;
        Line::new()
            .str("FAIL stack: a call of ")
            .str(section)
            .str(" used all the stack down to the end of .bss")
            .emit();
    }
    let total = records.as_slice().len() as u64;
    let mut line = Line::new();
    line.str("firmware: ")
        .uint(total - failed.min(total))
        .str(" of ")
        .uint(total);
    line.str(" records match the host, ")
        .uint(failed)
        .str(" mismatches")
        .emit();
    debug::exit(if failed == 0 {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    halt()
}

/// A fault (a bus fault, such as the stack running below the RAM, or an undefined
/// instruction) fails the run at once, naming the faulting instruction, instead of leaving the
/// emulator spinning in cortex-m-rt's default handler until the host test's timeout.
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    let mut line = Line::new();
    line.str("FAIL hard fault at pc ")
        .hex(u64::from(frame.pc()))
        .str(", lr ")
        .hex(u64::from(frame.lr()));
    line.emit();
    debug::exit(debug::EXIT_FAILURE);
    halt()
}

/// Waits for interrupts forever (after the emulator was asked to exit).
fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}
