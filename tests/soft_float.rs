//! The firmware's assembly f32 routines against the code they replace,
//! called in the real ELF in the virtual machine. The multiply, sum and
//! difference (`src/board/soft_float.rs`, every `*`, `+` and `-` on the
//! AVR) against avr-libc's routines; `math::round_i32`,
//! `math::sqrt_1ulp` (`src/board/sqrt.rs`) and the parser's
//! `math::decimal::quotient_f32` (`src/board/decimal.rs`) and
//! `math::decimal::lex_plain` (`src/board/lex.rs`) against their host
//! twins, and the RX ring's copy of a line's usual bytes
//! (`mill_rx_take_usual`, `src/board/serial.rs`) against
//! `protocol::take_usual_plain`. The multiply against the routine it replaces, avr-libc's `__mulsf3`
//! (`__mulsf3x`, then `__fp_round`: what avr-libc's `__mulsf3` runs), both
//! called in the real ELF in the virtual machine, bit for bit, on random and
//! edge operands. Where both operands and the product are normal, both must
//! also be the host's IEEE product (round to nearest, ties to even), and the
//! fast path must have answered; a zero times a finite number, or a zero
//! plus a normal one, must have taken the short way.

mod common;

use common::Rng;
use sim::{Vm, VmConfig};

/// Longest call, cycles (avr-libc's slowest path is a few hundred).
const MAX_CYCLES: u64 = 2_000;
/// The fast path's longest run, cycles: above it, the call went the slow way.
const FAST_MAX: u64 = 110;
/// The longest run for a zero times a finite number, or a zero plus a
/// normal one.
const ZERO_MAX: u64 = 45;
/// The sum's fast path's longest run.
const ADD_FAST_MAX: u64 = 200;
/// The rounding's fast path's longest run.
const ROUND_FAST_MAX: u64 = 120;
/// The table square root's longest run for a positive normal argument.
const SQRT_MAX: u64 = 140;
/// The decimal conversion's longest run (a byte and seven bits of the
/// normalising shift).
const QUOTIENT_MAX: u64 = 195;
/// The number lexer's longest run on a plain number (nine digits, zeros
/// waiting in the fraction).
const LEX_MAX: u64 = 520;
/// The RX copy's longest run a byte (a blank: every test), cycles, and
/// its call.
const RX_COPY_BYTE_MAX: u64 = 26;
const RX_COPY_CALL_MAX: u64 = 40;

/// The routines of the ELF, called in one virtual machine.
struct Routines {
    vm: Vm,
}

fn args(a: f32, b: f32) -> [(u8, u8); 8] {
    let (a, b) = (a.to_bits().to_le_bytes(), b.to_bits().to_le_bytes());
    [(22, a[0]), (23, a[1]), (24, a[2]), (25, a[3]), (18, b[0]), (19, b[1]), (20, b[2]), (21, b[3])]
}

impl Routines {
    fn new() -> Routines {
        Routines { vm: Vm::new(VmConfig::default()).expect("load firmware") }
    }

    fn addr(&self, name: &str) -> u32 {
        self.vm.symbol_addr(name).unwrap_or_else(|| panic!("{name} is not in the ELF"))
    }

    fn result(&self) -> u32 {
        u32::from_le_bytes([self.vm.reg(22), self.vm.reg(23), self.vm.reg(24), self.vm.reg(25)])
    }

    /// The firmware's routine at `addr`: the result's bits and the cycles
    /// it took.
    fn ours(&mut self, addr: u32, a: f32, b: f32) -> (u32, u64) {
        let cycles = self.vm.call(addr, &args(a, b), MAX_CYCLES).expect("the routine returns");
        assert_eq!(self.vm.reg(1), 0, "r1 is zero again after {addr:#x}({a:e}, {b:e})");
        (self.result(), cycles)
    }

    /// avr-libc's routine: its `x` part at `x_addr` (`__mulsf3x`,
    /// `__addsf3x`, entered with r26 and r27 cleared as avr-libc's
    /// `__addsf3` does; `__mulsf3x` does not read them), then `__fp_round`
    /// on what it left.
    fn avr_libc(&mut self, x_addr: u32, round: u32, a: f32, b: f32) -> u32 {
        let mut regs = args(a, b).to_vec();
        regs.extend([(26, 0), (27, 0)]);
        self.vm.call(x_addr, &regs, MAX_CYCLES).expect("avr-libc's routine returns");
        self.vm.call(round, &[], MAX_CYCLES).expect("__fp_round returns");
        self.result()
    }
}

fn is_normal_or_zero(x: f32) -> bool {
    x.is_normal() || x == 0.0
}

/// A normal float of biased exponent `e`: a random sign, random bits
/// where `frac_mask` has them.
fn normal(rng: &mut Rng, e: u32, frac_mask: u32) -> f32 {
    let sign = rng.next() & 0x8000_0000;
    f32::from_bits(sign | (e << 23) | (rng.next() & frac_mask))
}

/// Two floats: any bit patterns, or normal numbers of any exponent.
fn any_pair(rng: &mut Rng, normal_only: bool) -> (f32, f32) {
    if !normal_only {
        return (f32::from_bits(rng.next()), f32::from_bits(rng.next()));
    }
    let (ea, eb) = (1 + rng.next() % 254, 1 + rng.next() % 254);
    (normal(rng, ea, 0x7F_FFFF), normal(rng, eb, 0x7F_FFFF))
}

/// A signed zero and any bit pattern, in either order.
fn zero_and_any(rng: &mut Rng) -> (f32, f32) {
    let z = f32::from_bits(rng.next() & 0x8000_0000);
    if rng.next() & 1 == 0 {
        (z, f32::from_bits(rng.next()))
    } else {
        (f32::from_bits(rng.next()), z)
    }
}

/// Every pair of the edge values both routines are tried on first: zeros
/// of both signs, ones, a power of two, the extremes, the smallest
/// subnormal, the infinities and a NaN.
fn special_pairs() -> Vec<(f32, f32)> {
    let specials = [0.0f32, -0.0, 1.0, -1.0, 2.0, 0.5, f32::MAX, f32::MIN_POSITIVE, 1e-45, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
    specials.iter().flat_map(|&a| specials.iter().map(move |&b| (a, b))).collect()
}

/// Factors of every kind: any bit pattern (zeros, subnormals, infinities,
/// NaN among them), normal numbers of any exponent, exponent sums at the
/// fast path's limits, and short significands (their products are ties
/// and carries out of the rounding more often than random ones).
fn factors(rng: &mut Rng, i: u32) -> (f32, f32) {
    match i % 7 {
        k @ (0 | 1) => any_pair(rng, k == 1),
        2 => {
            // ea + eb − 128 around 0 and around 251.
            let ea = 1 + rng.next() % 254;
            let t = if rng.next() & 1 == 0 { (rng.next() % 5) as i32 - 2 } else { 249 + (rng.next() % 5) as i32 };
            let eb = (t + 128 - ea as i32).clamp(1, 254) as u32;
            (normal(rng, ea, 0x7F_FFFF), normal(rng, eb, 0x7F_FFFF))
        }
        3 => {
            // Short significands: exact products, ties.
            let (ea, eb) = (100 + rng.next() % 56, 100 + rng.next() % 56);
            (normal(rng, ea, 0x7F_F000), normal(rng, eb, 0x7F_F000))
        }
        4 => {
            // Products a hair from 2: rounding carries into the exponent
            // (a significand times the f32 nearest 2 over it), at exponent
            // sums anywhere and at the fast path's limits.
            let fa = rng.next() & 0x7F_FFFF;
            let fb = (2.0 / f32::from_bits(0x3F80_0000 | fa)).to_bits() & 0x7F_FFFF;
            let ea = 1 + rng.next() % 254;
            let t = [(rng.next() % 5) as i32 - 2, 248 + (rng.next() % 7) as i32, (rng.next() % 254) as i32][(rng.next() % 3) as usize];
            let eb = (t + 128 - ea as i32).clamp(1, 254) as u32;
            let a = f32::from_bits(normal(rng, ea, 0).to_bits() | fa);
            (a, f32::from_bits(normal(rng, eb, 0).to_bits() | fb))
        }
        5 => zero_and_any(rng),
        _ => {
            // The values a streamed line multiplies: mm, steps/mm, speeds.
            let x = (rng.next() % 2_000_000) as f32 / 1000.0 - 1000.0;
            let y = (rng.next() % 400_000) as f32 / 997.0;
            (x, y)
        }
    }
}

#[test]
fn the_assembly_multiply_is_avr_libcs_bit_for_bit_and_ieee_where_both_are_normal() {
    let mut m = Routines::new();
    let (ours, mulx, round) = (m.addr("__wrap___mulsf3"), m.addr("__mulsf3x"), m.addr("__fp_round"));
    let mut rng = Rng(0x5EED_F10A);
    let mut pairs = special_pairs();
    pairs.extend((0..60_000).map(|i| factors(&mut rng, i)));
    let (mut fast, mut fast_cycles, mut fast_max, mut zeros) = (0u32, 0u64, 0u64, 0u32);
    for &(a, b) in &pairs {
        let (got, cycles) = m.ours(ours, a, b);
        let want = m.avr_libc(mulx, round, a, b);
        assert_eq!(got, want, "{a:e} ({:#010x}) * {b:e} ({:#010x}): {got:#010x}, avr-libc {want:#010x}", a.to_bits(), b.to_bits());
        let ieee = a * b;
        if a.is_normal() && b.is_normal() && ieee.is_normal() && (ieee.to_bits() & 0x7F80_0000) != 0x7F00_0000 {
            assert_eq!(got, ieee.to_bits(), "{a:e} * {b:e}: {got:#010x}, IEEE {:#010x}", ieee.to_bits());
            let t = ((a.to_bits() >> 23) & 0xFF) as i32 + ((b.to_bits() >> 23) & 0xFF) as i32 - 128;
            if (0..=252).contains(&t) {
                assert!(cycles <= FAST_MAX, "{a:e} * {b:e}: {cycles} cycles, not the fast path");
                fast += 1;
                fast_cycles += cycles;
                fast_max = fast_max.max(cycles);
            }
        } else if (a == 0.0 && b.is_finite()) || (b == 0.0 && a.is_finite()) {
            assert!(cycles <= ZERO_MAX, "{a:e} * {b:e}: {cycles} cycles, not the zero path");
            zeros += 1;
        } else if is_normal_or_zero(a) && is_normal_or_zero(b) && is_normal_or_zero(ieee) && !ieee.is_infinite() {
            assert_eq!(got, ieee.to_bits(), "{a:e} * {b:e}: {got:#010x}, IEEE {:#010x}", ieee.to_bits());
        }
    }
    assert!(fast > 30_000, "only {fast} products took the fast path");
    assert!(zeros > 50, "only {zeros} products of a zero");
    println!("fast path: {fast} of {} products, mean {} cycles, max {fast_max} (call to ret)", pairs.len(), fast_cycles / fast as u64);
}

/// Terms of every kind: any bit pattern, normal numbers of any exponent,
/// exponent differences from 0 to 30 (y shifted by bytes and bits, or
/// dropped), near cancellations (x − x·(1 ± a few last places)), short
/// significands (ties), exponents at the fast path's limits, zeros, powers
/// of two less the smallest terms that change them, and the values a
/// streamed line adds.
fn terms(rng: &mut Rng, i: u32) -> (f32, f32) {
    let near = |rng: &mut Rng, e: u32| (e as i32 + (rng.next() % 61) as i32 - 30).clamp(1, 254) as u32;
    match i % 9 {
        k @ (0 | 1) => any_pair(rng, k == 1),
        2 => {
            let ea = 1 + rng.next() % 254;
            let eb = near(rng, ea);
            (normal(rng, ea, 0x7F_FFFF), normal(rng, eb, 0x7F_FFFF))
        }
        3 => {
            // x and nearly −x (or nearly −2x, −x/2): cancellation.
            let e = 30 + rng.next() % 200;
            let a = normal(rng, e, 0x7F_FFFF);
            let k = [1.0f32, 2.0, 0.5][(rng.next() % 3) as usize];
            let d = (rng.next() % 9) as i32 - 4;
            let b = f32::from_bits(((a * k).to_bits() as i32 + d) as u32);
            (a, if rng.next() & 1 == 0 { -b } else { b })
        }
        4 => {
            // Short significands: ties.
            let ea = 60 + rng.next() % 100;
            let eb = near(rng, ea);
            (normal(rng, ea, 0x7F_0000), normal(rng, eb, 0x7C_0003))
        }
        5 => {
            // The fast path's exponent limits (26 and 252).
            let e = [24 + rng.next() % 5, 250 + rng.next() % 5][(rng.next() & 1) as usize];
            let eb = near(rng, e).min(254);
            (normal(rng, e, 0x7F_FFFF), normal(rng, eb, 0x7F_FFFF))
        }
        6 => zero_and_any(rng),
        7 => {
            // A power of two less a term 22 to 27 exponents below it: the
            // difference may drop to the next binade (the smallest terms
            // that still change it).
            let e = 30 + rng.next() % 200;
            let a = normal(rng, e, 0);
            let eb = e - 22 - rng.next() % 6;
            let b = normal(rng, eb, 0x7F_FFFF);
            (a, if (a > 0.0) == (b > 0.0) { -b } else { b })
        }
        _ => {
            // mm, speeds, times.
            let x = (rng.next() % 2_000_000) as f32 / 1000.0 - 1000.0;
            let y = (rng.next() % 400_000) as f32 / 997.0 * [1.0, 1e-3, 1e3][(rng.next() % 3) as usize];
            (x, y)
        }
    }
}

#[test]
fn the_assembly_sum_and_difference_are_avr_libcs_bit_for_bit_and_ieee_where_all_are_normal() {
    let mut m = Routines::new();
    let (add, sub, addx, round) = (m.addr("__wrap___addsf3"), m.addr("__wrap___subsf3"), m.addr("__addsf3x"), m.addr("__fp_round"));
    let mut rng = Rng(0xADD5_0B7A);
    let mut pairs = special_pairs();
    pairs.extend((0..60_000).map(|i| terms(&mut rng, i)));
    let (mut fast, mut fast_cycles, mut fast_max, mut zeros) = (0u32, 0u64, 0u64, 0u32);
    for &(a, b) in &pairs {
        for (addr, name) in [(add, "+"), (sub, "-")] {
            let (got, cycles) = m.ours(addr, a, b);
            // a − b is a + (−b), as avr-libc's __subsf3 makes it.
            let b = if name == "-" { -b } else { b };
            let want = m.avr_libc(addx, round, a, b);
            let ctx =
                format!("{a:e} ({:#010x}) + {b:e} ({:#010x}) by {name}: {got:#010x}, avr-libc {want:#010x}", a.to_bits(), b.to_bits());
            assert_eq!(got, want, "{ctx}");
            let ieee = a + b;
            let ea = (a.to_bits() >> 23) & 0xFF;
            let eb = (b.to_bits() >> 23) & 0xFF;
            if (a == 0.0 && b.is_normal()) || (b == 0.0 && a.is_normal()) {
                assert_eq!(got, ieee.to_bits(), "{ctx}, IEEE {:#010x}", ieee.to_bits());
                assert!(cycles <= ZERO_MAX, "{ctx}: {cycles} cycles, not the zero path");
                zeros += 1;
            }
            if a.is_normal() && b.is_normal() && (ieee.is_normal() || ieee == 0.0) {
                assert_eq!(got, ieee.to_bits(), "{ctx}, IEEE {:#010x}", ieee.to_bits());
                if (26..=252).contains(&ea) && (26..=252).contains(&eb) {
                    assert!(cycles <= ADD_FAST_MAX, "{ctx}: {cycles} cycles, not the fast path");
                    fast += 1;
                    fast_cycles += cycles;
                    fast_max = fast_max.max(cycles);
                }
            }
        }
    }
    assert!(fast > 60_000, "only {fast} sums took the fast path");
    assert!(zeros > 1_000, "only {zeros} sums of a zero");
    println!("fast path: {fast} of {} sums, mean {} cycles, max {fast_max} (call to ret)", 2 * pairs.len(), fast_cycles / fast as u64);
}

/// Floats to round: any bit pattern, every exponent from 2⁻⁸ to 2³² with a
/// random significand, halves (k + ½, the ties), and the steps a move
/// ends on (mm × steps/mm).
fn to_round(rng: &mut Rng, i: u32) -> f32 {
    match i % 4 {
        0 => f32::from_bits(rng.next()),
        1 => {
            let e = 119 + rng.next() % 40;
            f32::from_bits((rng.next() & 0x8000_0000) | (e << 23) | (rng.next() & 0x7F_FFFF))
        }
        2 => ((rng.next() % 20_000_000) as i32 - 10_000_000) as f32 + 0.5,
        _ => ((rng.next() % 2_000_000) as f32 / 1000.0 - 1000.0) * [100.0, 80.0, 400.0, 3200.0][(rng.next() % 4) as usize],
    }
}

#[test]
fn the_assembly_rounding_is_its_host_twins_on_floats_of_every_kind() {
    let mut m = Routines::new();
    let f = m.addr("mill_round_i32");
    let mut rng = Rng(0x0123_4567);
    let mut xs =
        vec![0.0f32, -0.0, 0.5, -0.5, 0.499_999_97, 1.5, 2.5, -2.5, 8_388_607.5, 8_388_608.0, 2_147_483_520.0, -2_147_483_648.0, 3e9, -3e9];
    xs.extend([f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MIN_POSITIVE, 1e-45]);
    xs.extend((0..40_000).map(|i| to_round(&mut rng, i)));
    let (mut fast, mut fast_cycles, mut fast_max) = (0u32, 0u64, 0u64);
    for &x in &xs {
        let (got, cycles) = m.ours(f, x, 0.0);
        let want = mill::math::round_i32(x);
        assert_eq!(got as i32, want, "round_i32({x:e}) ({:#010x}): {got}, the twin {want}", x.to_bits());
        if (126..=149).contains(&((x.to_bits() >> 23) & 0xFF)) {
            assert!(cycles <= ROUND_FAST_MAX, "round_i32({x:e}): {cycles} cycles, not the fast path");
            fast += 1;
            fast_cycles += cycles;
            fast_max = fast_max.max(cycles);
        }
    }
    assert!(fast > 15_000, "only {fast} roundings took the fast path");
    println!("fast path: {fast} of {} roundings, mean {} cycles, max {fast_max} (call to ret)", xs.len(), fast_cycles / fast as u64);
}

#[test]
fn the_assembly_square_root_is_its_host_twins_and_avr_libcs_for_the_rest() {
    let mut m = Routines::new();
    let f = m.addr("mill_sqrt_1ulp");
    let libc = m.addr("sqrt");
    let mut rng = Rng(0x5157_0001);
    let mut xs = vec![1.0f32, 2.0, 4.0, 0.25, 3.999_999_8, 1.000_000_1, f32::MIN_POSITIVE, f32::MAX, 100.0, 2500.0];
    // Every knot of both octaves and the floats either side of it.
    for i in 0..256u32 {
        let k = f32::from_bits((127 << 23) | (i % 128) << 16) * if i < 128 { 1.0 } else { 2.0 };
        xs.extend([k, f32::from_bits(k.to_bits() - 1), f32::from_bits(k.to_bits() + 1)]);
    }
    // Random positive normals, random bits of every kind, speeds² and squares.
    xs.extend((0..20_000).map(|_| f32::from_bits(0x0080_0000 + rng.next() % 0x7F00_0000)));
    xs.extend((0..5_000).map(|_| f32::from_bits(rng.next())));
    xs.extend((1..=3000).map(|v| (v * v) as f32));
    // The rest goes to avr-libc: zeros, negatives, subnormals, infinities, NaNs.
    xs.extend([
        0.0f32,
        -0.0,
        -1.0,
        -f32::MIN_POSITIVE,
        f32::from_bits(1),
        f32::from_bits(0x007F_FFFF),
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
    ]);
    // The callee-saved registers (r2–r17, r28, r29) hold these before the call.
    let saved: Vec<(u8, u8)> = (2..=17).chain(28..=29).map(|r| (r, 0xA0 ^ r)).collect();
    let (mut normal, mut cycles_sum, mut cycles_max, mut other) = (0u64, 0u64, 0u64, 0u32);
    for &x in &xs {
        let mut regs = args(x, 0.0).to_vec();
        regs.extend(&saved);
        let cycles = m.vm.call(f, &regs, MAX_CYCLES).expect("mill_sqrt_1ulp returns");
        assert_eq!(m.vm.reg(1), 0, "r1 after sqrt({x:e})");
        for &(r, v) in &saved {
            assert_eq!(m.vm.reg(r), v, "r{r} after sqrt({x:e})");
        }
        let got = m.result();
        let b = x.to_bits();
        if b.wrapping_sub(0x0080_0000) < 0x7F00_0000 {
            let want = mill::math::sqrt_1ulp_plain(x).to_bits();
            assert_eq!(got, want, "sqrt_1ulp({x:e}) ({b:#010x}): {got:#010x}, the twin {want:#010x}");
            normal += 1;
            cycles_sum += cycles;
            cycles_max = cycles_max.max(cycles);
            assert!(cycles <= SQRT_MAX, "sqrt_1ulp({x:e}): {cycles} cycles");
        } else {
            let (want, _) = m.ours(libc, x, 0.0);
            assert_eq!(got, want, "sqrt_1ulp({x:e}) ({b:#010x}) is avr-libc's sqrt: {got:#010x} vs {want:#010x}");
            other += 1;
        }
    }
    assert!(normal > 25_000 && other > 1_000, "{normal} normal, {other} other");
    println!("positive normals: {normal}, mean {} cycles, max {cycles_max} (call to ret); {other} to avr-libc", cycles_sum / normal);
}

#[test]
fn the_assembly_decimal_conversion_is_its_host_twins() {
    let mut m = Routines::new();
    let f = m.addr("mill_quotient_f32");
    let mut rng = Rng(0xDEC1_0001);
    // (mantissa, power of ten): the edges of every branch, then the usual
    // words of a G-code file (up to 6 integer and 4 fraction digits) and
    // random mantissas below and above 2^24 at every scale.
    let mut cases: Vec<(u32, u16)> = Vec::new();
    for s in 0..=11u16 {
        for m in [0u32, 1, 2, 9, 10, 99, 255, 256, 257, 65_535, 65_536, 65_537, 999_999, (1 << 24) - 1, 1 << 24, u32::MAX] {
            cases.push((m, s));
        }
    }
    cases.extend([(1, 256), (5, 257), (19_998, 259)]);
    cases.extend((0..30_000).map(|_| (rng.next() % 10_000_000, (1 + rng.next() % 4) as u16)));
    cases.extend((0..30_000).map(|_| (rng.next() >> (rng.next() % 32), (rng.next() % 12) as u16)));
    // The saved registers (r2–r17, r28, r29) hold these before the call.
    let saved: Vec<(u8, u8)> = (2..=17).chain(28..=29).map(|r| (r, 0x5A ^ r)).collect();
    let (mut answered, mut none, mut cycles_sum, mut cycles_max) = (0u64, 0u64, 0u64, 0u64);
    for &(mant, s) in &cases {
        let b = mant.to_le_bytes();
        let mut regs = vec![(22, b[0]), (23, b[1]), (24, b[2]), (25, b[3]), (20, s as u8), (21, (s >> 8) as u8)];
        regs.extend(&saved);
        // The library passes s as a u8 (a larger one is no answer before the call).
        let Ok(_) = u8::try_from(s) else {
            assert_eq!(mill::math::decimal::quotient_f32_plain(mant, s), None, "{mant} / 10^{s}");
            continue;
        };
        let cycles = m.vm.call(f, &regs, MAX_CYCLES).expect("mill_quotient_f32 returns");
        assert_eq!(m.vm.reg(1), 0, "r1 after {mant} / 10^{s}");
        for &(r, v) in &saved {
            assert_eq!(m.vm.reg(r), v, "r{r} after {mant} / 10^{s}");
        }
        let got = m.result();
        match mill::math::decimal::quotient_f32_plain(mant, s) {
            Some(v) => {
                assert_eq!(got, v.to_bits(), "{mant} / 10^{s}: {got:#010x}, the twin {:#010x} ({v:e})", v.to_bits());
                answered += 1;
                cycles_sum += cycles;
                cycles_max = cycles_max.max(cycles);
                assert!(cycles <= QUOTIENT_MAX, "{mant} / 10^{s}: {cycles} cycles");
            }
            None => {
                assert_eq!(got, 0, "{mant} / 10^{s}: {got:#010x}, the twin has no answer");
                none += 1;
            }
        }
    }
    assert!(answered > 45_000 && none > 10_000, "{answered} answered, {none} not");
    println!("answered: {answered}, mean {} cycles, max {cycles_max} (call to ret); {none} without an answer", cycles_sum / answered);
}

#[test]
fn the_assembly_number_lexer_is_its_host_twins() {
    let mut m = Routines::new();
    let f = m.addr("mill_lex_plain");
    // A free stretch of RAM below the stack for the text (the VM is not
    // running: nothing else uses it).
    const TEXT: u16 = 0x1C00;
    let mut rng = Rng(0x1E8_0001);
    let alphabet = b"0123456789.-+eE \tXY;(";
    let mut texts: Vec<Vec<u8>> = [
        &b"19.998 Y0.100"[..],
        b"0.100",
        b"1",
        b"",
        b".",
        b"-",
        b"123456",
        b"1234567",
        b"999999.5",
        b"1.23456789",
        b"1.234567890",
        b"0.0000001",
        b"000000001",
        b"12 .5",
        b"12. 5",
        b"12 5",
        b"1.5 .5",
        b"1e5",
        b"1E5",
        b"1..2",
        b"1.2.3",
        b"1+",
        b"1-",
        b"1 \t ",
        b"1 \t X",
        b"1 \t 2",
        b"1. ",
        b".5",
        b"5.",
        b"0.000",
        b"00.00100",
    ]
    .iter()
    .map(|t| t.to_vec())
    .collect();
    for _ in 0..40_000 {
        let len = (rng.next() % 14) as usize;
        let t: Vec<u8> = (0..len)
            .map(|_| {
                let r = rng.next();
                // Mostly digits, some points and blanks, a few of the rest.
                match r % 8 {
                    0..=4 => b'0' + (r >> 8) as u8 % 10,
                    5 => b'.',
                    6 => b' ',
                    _ => alphabet[(r >> 8) as usize % alphabet.len()],
                }
            })
            .collect();
        texts.push(t);
    }
    let saved: Vec<(u8, u8)> = (2..=17).chain(28..=29).map(|r| (r, 0x3C ^ r)).collect();
    let (mut plain, mut cycles_sum, mut cycles_max) = (0u64, 0u64, 0u64);
    for t in &texts {
        // The byte after the text is a digit: the routine must stop at its length.
        let mut ram = t.clone();
        ram.push(b'7');
        m.vm.write_ram(TEXT, &ram);
        let mut regs = vec![(24, TEXT as u8), (25, (TEXT >> 8) as u8), (22, t.len() as u8)];
        regs.extend(&saved);
        let cycles = m.vm.call(f, &regs, MAX_CYCLES).expect("mill_lex_plain returns");
        assert_eq!(m.vm.reg(1), 0, "r1 after {:?}", String::from_utf8_lossy(t));
        for &(r, v) in &saved {
            assert_eq!(m.vm.reg(r), v, "r{r} after {:?}", String::from_utf8_lossy(t));
        }
        let r: Vec<u8> = (18..=25).map(|r| m.vm.reg(r)).collect();
        let got = (u32::from_le_bytes([r[0], r[1], r[2], r[3]]), r[4], r[5]);
        let want = mill::math::decimal::lex_plain_plain(t);
        assert_eq!(got, want, "{:?}", String::from_utf8_lossy(t));
        assert_eq!((r[6], r[7]), (0, 0), "r24, r25 after {:?}", String::from_utf8_lossy(t));
        if want.2 != 0 {
            assert!(cycles <= LEX_MAX, "{:?}: {cycles} cycles", String::from_utf8_lossy(t));
            plain += 1;
            cycles_sum += cycles;
            cycles_max = cycles_max.max(cycles);
        }
        if t == b"19.998 Y0.100" {
            println!("19.998: {cycles} cycles");
        }
    }
    assert!(plain > 5_000, "only {plain} plain numbers");
    println!("plain numbers: {plain} of {}, mean {} cycles, max {cycles_max} (call to ret)", texts.len(), cycles_sum / plain);
}

/// The address of the firmware's static whose mangled name ends in `tail`.
fn static_addr(vm: &Vm, tail: &str) -> u16 {
    vm.symbols().find(tail).into_iter().find(|s| s.name.ends_with(tail)).unwrap_or_else(|| panic!("no {tail}")).addr as u16
}

#[test]
fn the_assembly_rx_copy_is_its_host_twins() {
    let mut m = Routines::new();
    let f = m.addr("mill_rx_take_usual");
    let (buf, head_at, tail_at) =
        (static_addr(&m.vm, "6serial6RX_BUF"), static_addr(&m.vm, "6serial7RX_HEAD"), static_addr(&m.vm, "6serial7RX_TAIL"));
    // The line's free slots, in a free stretch of RAM below the stack (the
    // VM is not running), with a fence after them the copy must not touch.
    const DST: u16 = 0x1C00;
    let mut rng = Rng(0x4C1_0001);
    let saved: Vec<(u8, u8)> = (2..=17).chain(28..=29).map(|r| (r, 0x5A ^ r)).collect();
    let (mut bytes, mut cycles_sum, mut cycles_max_per_byte) = (0u64, 0u64, 0u64);
    for i in 0..20_000u32 {
        // Mostly a G-code line's bytes, some blanks, marks, line ends and
        // bytes no line holds.
        let ring: [u8; 256] = core::array::from_fn(|_| {
            let r = rng.next();
            match r % 16 {
                0..=7 => b"0123456789.-"[(r >> 8) as usize % 12],
                8..=10 => b"GXYZFMN$"[(r >> 8) as usize % 8],
                11 => b' ',
                12 => b'\t',
                13 => b"()*;!\"'"[(r >> 8) as usize % 7],
                14 => b"\n\r"[(r >> 8) as usize % 2],
                _ => (r >> 8) as u8,
            }
        });
        let tail = rng.next() as u8;
        let head = tail.wrapping_add((rng.next() % 256) as u8);
        let room = match i % 4 {
            0 => 256,
            1 => (rng.next() % 8) as u16,
            2 => 300,
            _ => (rng.next() % 257) as u16,
        };
        let started = rng.next().is_multiple_of(2);
        let fence = vec![0xA5u8; room as usize + 8];
        m.vm.write_ram(buf, &ring);
        m.vm.write_ram(head_at, &[head]);
        m.vm.write_ram(tail_at, &[tail]);
        m.vm.write_ram(DST, &fence);
        let mut regs = vec![(24, DST as u8), (25, (DST >> 8) as u8), (22, room as u8), (23, (room >> 8) as u8), (20, started as u8)];
        regs.extend(&saved);
        let cycles = m.vm.call(f, &regs, 20_000).expect("mill_rx_take_usual returns");
        assert_eq!(m.vm.reg(1), 0, "r1, case {i}");
        for &(r, v) in &saved {
            assert_eq!(m.vm.reg(r), v, "r{r}, case {i}");
        }
        let mut want_dst = vec![0xA5u8; room as usize + 8];
        let mut want_tail = tail;
        let n = mill::protocol::take_usual_plain(&ring, head, &mut want_tail, &mut want_dst[..room as usize], started);
        let got_n = u16::from_le_bytes([m.vm.reg(24), m.vm.reg(25)]) as usize;
        assert_eq!(got_n, n, "case {i}: room {room}, started {started}");
        assert_eq!(m.vm.read_u8(tail_at), want_tail, "case {i}: the tail");
        assert_eq!(m.vm.read_u8(head_at), head, "case {i}: the head");
        let got_dst: Vec<u8> = (0..want_dst.len() as u16).map(|k| m.vm.read_u8(DST + k)).collect();
        assert_eq!(got_dst, want_dst, "case {i}: the line's slots and the fence after them");
        if n > 0 {
            bytes += n as u64;
            cycles_sum += cycles;
            cycles_max_per_byte = cycles_max_per_byte.max(cycles.saturating_sub(RX_COPY_CALL_MAX) / n as u64);
        }
        assert!(cycles <= RX_COPY_CALL_MAX + RX_COPY_BYTE_MAX * (n as u64 + 1), "case {i}: {cycles} cycles for {n} bytes");
    }
    assert!(bytes > 20_000, "only {bytes} bytes copied");
    println!(
        "{bytes} bytes copied, {:.1} cycles a byte with the calls, at most {cycles_max_per_byte} a byte beyond a call",
        cycles_sum as f64 / bytes as f64
    );
}
