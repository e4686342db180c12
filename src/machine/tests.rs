//! Host tests of the controller ([`Machine`]) on the fake board
//! ([`crate::fake_board`]): homing, a tool change with its EEPROM journal,
//! G37, a hard-limit alarm and a feed hold, driven through the public API
//! (`boot`, `push_bytes`, `idle`) as the firmware's main loop drives it, and
//! checked on what the board saw: steps, physical positions, replies,
//! EEPROM bytes and outputs.
//!
//! Each test's doc says how it was checked to fail: the code it guards was
//! broken once by hand (not committed) and the test failed. The functions
//! named are those from before the one-way pipeline restructuring
//! moved some of them (the git history has that code).

use crate::atc::tools::{
    pocket_bit, Journal, ToolState, ToolTable, ALL_POCKETS, EEPROM_JOURNAL_ADDR, EEPROM_STATE_ADDR, EEPROM_TABLE_ADDR,
};
use crate::fake_board::{At, Beam, Event, FakeBoard, Input, Output, Tool};
use crate::machine::{Machine, State};
use crate::protocol::LineAssembler;

/// A machine on a fake board.
struct Rig {
    m: Box<Machine>,
    io: FakeBoard,
    asm: LineAssembler,
}

impl Rig {
    /// Power on with `io` (its EEPROM, switches and motor positions).
    fn boot(mut io: FakeBoard) -> Rig {
        let mut m = Box::new(Machine::new());
        m.boot(&mut io, F!("power-on"), false);
        Rig { m, io, asm: LineAssembler::new() }
    }

    /// Send `line` as a host does; what the firmware printed until its `ok`.
    fn send(&mut self, line: &str) -> String {
        self.io.take_out();
        let bytes = format!("{line}\n");
        self.m.push_bytes(&mut self.asm, bytes.bytes(), &mut self.io);
        let r = self.io.take_out();
        assert!(r.ends_with("ok\n"), "{line:?}: no ok: {r:?}");
        r
    }

    /// Send `line`, which must succeed with no error or alarm; then wait for
    /// its motion to end (M400).
    fn ok(&mut self, line: &str) -> String {
        let r = self.send(line);
        assert!(!r.contains("Error") && !r.contains("ALARM"), "{line:?}: {r:?}");
        let w = self.send("M400");
        let w: Vec<&str> = w.lines().filter(|l| *l != "busy:processing").collect();
        assert_eq!(w, ["ok"], "M400 after {line:?}");
        r
    }

    /// Send `line`, which must be refused: its reply.
    fn refused(&mut self, line: &str) -> String {
        let r = self.send(line);
        assert!(r.contains("Error:"), "{line:?} accepted: {r:?}");
        r
    }

    /// Main-loop turns until `done` or `polls` turns.
    fn idle_until(&mut self, polls: u32, mut done: impl FnMut(&Machine, &FakeBoard) -> bool) -> bool {
        for _ in 0..polls {
            if done(&self.m, &self.io) {
                return true;
            }
            self.m.idle(&mut self.io);
        }
        done(&self.m, &self.io)
    }

    /// One `?` status line.
    fn status(&mut self) -> String {
        self.io.take_out();
        self.io.now(Event::Status);
        self.m.idle(&mut self.io);
        self.io.take_out()
    }

    /// Physical X Y Z.
    fn xyz(&self) -> [i64; 3] {
        [self.io.phys[0], self.io.phys[1], self.io.phys[2]]
    }

    /// Counted X Y Z.
    fn counted(&self) -> [i32; 3] {
        [self.io.pos[0], self.io.pos[1], self.io.pos[2]]
    }
}

/// Runs of `axis` in `steps[from..]`: signed lengths of its stretches in one direction.
fn runs(io: &FakeBoard, axis: usize, from: usize) -> Vec<i64> {
    let mut out: Vec<i64> = Vec::new();
    for s in &io.steps[from..] {
        if s.axes & (1 << axis) == 0 {
            continue;
        }
        let d = if s.neg & (1 << axis) != 0 { -1 } else { 1 };
        match out.last_mut() {
            Some(r) if (*r > 0) == (d > 0) => *r += d,
            _ => out.push(d),
        }
    }
    out
}

/// Indices in `steps[from..]` (absolute) of the first and last step of `axis`.
fn span(io: &FakeBoard, axis: usize, from: usize) -> Option<(usize, usize)> {
    let idx: Vec<usize> = (from..io.steps.len()).filter(|&i| io.steps[i].axes & (1 << axis) != 0).collect();
    Some((*idx.first()?, *idx.last()?))
}

const AXES: [&str; 3] = ["X", "Y", "Z"];

// ---- Homing ----------------------------------------------------------------

/// One axis' homing from `start` steps above its switch: fast seek to the
/// switch, 1 mm pull-off, slow seek back onto it, 1 mm pull-off.
fn homing_runs(start: i64) -> Vec<i64> {
    vec![-start, 100, -100, 100]
}

/// G28 homes Z, then Y, then X, one axis at a time, each with its seek,
/// pull-off, slow seek and pull-off, and ends 1 mm (the pull-off) from where
/// every switch closes, counted and physically.
///
/// Checked to fail: with the final `home_pulloff` of `home_axes` removed
/// (X, Y, Z end at 0 and the runs lose their last +100), and with the axis
/// order changed to X, Y, Z.
#[test]
fn g28_homes_z_then_y_then_x_and_ends_one_pulloff_from_each_switch() {
    let mut io = FakeBoard::new();
    io.place([1500, 1200, 900, 0]);
    let mut r = Rig::boot(io);
    assert_eq!(r.m.homed, 0);
    r.ok("G28");
    assert_eq!(r.xyz(), [100, 100, 100]);
    assert_eq!(r.counted(), [100, 100, 100]);
    assert_eq!(r.m.homed & 0b111, 0b111);
    assert_eq!(runs(&r.io, 0, 0), homing_runs(1500));
    assert_eq!(runs(&r.io, 1, 0), homing_runs(1200));
    assert_eq!(runs(&r.io, 2, 0), homing_runs(900));
    let (z0, z1) = span(&r.io, 2, 0).unwrap();
    let (y0, y1) = span(&r.io, 1, 0).unwrap();
    let (x0, _) = span(&r.io, 0, 0).unwrap();
    assert!(z0 == 0 && z1 < y0 && y1 < x0, "order Z, Y, X: Z {z0}..{z1}, Y {y0}..{y1}, X {x0}");
    assert!(r.io.steps.iter().all(|s| s.axes.count_ones() == 1), "one axis at a time");
    assert_eq!(r.io.steps.iter().filter(|s| s.axes & 8 != 0).count(), 0, "the carousel stays");
    // The user sees machine X 1, Y 1, Z −1 (+Z up).
    let st = r.status();
    assert!(st.starts_with("<Idle|MPos:1.000,1.000,-1.000|"), "{st}");
    // A move after homing: no hard limit, exact.
    r.ok("G0 X10 Y20 Z-30");
    assert_eq!(r.xyz(), [1000, 2000, 3000]);
}

/// Every mask (G28 X, G28 Y Z, ...) homes exactly its axes, in the order
/// Z, Y, X, and leaves the others where they are (and unhomed); `$H` homes all.
///
/// Checked to fail: with `if mask & (1 << axis) == 0 { continue; }` removed
/// from `home_axes` (every axis homes whatever the mask).
#[test]
fn g28_with_axis_words_homes_only_those_axes_in_z_y_x_order() {
    for mask in 1u8..8 {
        let mut io = FakeBoard::new();
        io.place([700, 800, 900, 0]);
        let mut r = Rig::boot(io);
        let words: Vec<&str> = (0..3).filter(|a| mask & (1 << a) != 0).map(|a| AXES[a]).collect();
        let line = format!("G28 {}", words.join(" "));
        r.ok(&line);
        let mut last_end = None;
        for a in [2usize, 1, 0] {
            let start = [700, 800, 900][a];
            if mask & (1 << a) != 0 {
                assert_eq!(runs(&r.io, a, 0), homing_runs(start), "{line}: axis {a}");
                assert_eq!(r.io.phys[a], 100, "{line}: axis {a}");
                assert_eq!(r.io.pos[a], 100, "{line}: axis {a}");
                let (s, e) = span(&r.io, a, 0).unwrap();
                if let Some(prev) = last_end {
                    assert!(s > prev, "{line}: axis {a} homed before the one after it");
                }
                last_end = Some(e);
            } else {
                assert!(runs(&r.io, a, 0).is_empty(), "{line}: axis {a} moved");
                assert_eq!(r.io.phys[a], start);
            }
        }
        assert_eq!(r.m.homed & 0b111, mask, "{line}");
    }
    let mut io = FakeBoard::new();
    io.place([700, 800, 900, 0]);
    let mut r = Rig::boot(io);
    r.ok("$H");
    assert_eq!(r.xyz(), [100, 100, 100]);
}

/// A switch already closed at the start (at its trip point, or past it):
/// the axis first moves off it by the pull-off, then homes as usual.
///
/// Checked to fail: with the "starting on the switch" pull-off removed from
/// `home_axes` (the seek trips at once: the runs and positions differ).
#[test]
fn homing_from_a_closed_switch_moves_off_it_first() {
    for start in [[0i64, -10, 900], [-10, 0, 0], [0, 0, 0]] {
        let mut io = FakeBoard::new();
        io.place([start[0], start[1], start[2], 0]);
        let mut r = Rig::boot(io);
        r.ok("G28");
        assert_eq!(r.xyz(), [100, 100, 100], "from {start:?}");
        for a in 0..3 {
            let want = if start[a] <= 0 {
                // Off by 1 mm, back to the switch, then the usual cycle from 1 mm.
                let mut v = vec![100];
                v.extend(homing_runs(100 + start[a]));
                v
            } else {
                homing_runs(start[a])
            };
            assert_eq!(runs(&r.io, a, 0), want, "from {start:?}, axis {a}");
        }
    }
}

/// A switch that never closes (its cable cut): the seek goes the travel
/// plus 10 % (49.5 mm), then `ALARM:homing failed`; the axes after it never
/// move, the spindle is off, the machine is in alarm and refuses motion.
///
/// Checked to fail: with `home_fail` in `home_axes` replaced by a plain
/// `continue` (no alarm, X homes).
#[test]
fn a_switch_never_found_raises_homing_failed_and_nothing_else_moves() {
    let mut io = FakeBoard::new();
    io.place([700, 800, 900, 0]);
    io.now(Event::Force(Input::Home(1), Some(false)));
    let mut r = Rig::boot(io);
    let out = r.send("G28");
    assert!(out.contains("ALARM:homing failed\n"), "{out}");
    assert!(out.contains("Error:homing failed: switch not found\n"), "{out}");
    assert_eq!(runs(&r.io, 2, 0), homing_runs(900), "Z homed first");
    assert_eq!(runs(&r.io, 1, 0), [-4950], "Y sought 45 mm + 10 %");
    assert!(runs(&r.io, 0, 0).is_empty(), "X never moved");
    assert_eq!((r.m.state, r.m.homed), (State::Alarm, 0));
    assert_eq!(r.io.spindle, 0);
    let n = r.io.step_count();
    assert!(r.refused("G0 X5").contains("alarm"));
    assert_eq!(r.io.step_count(), n);
}

/// Real switches: with 0.2 mm of hysteresis (20 steps, less than the 1 mm
/// pull-off) homing ends exactly as with ideal ones, each switch closed and
/// opened twice, and the first move raises no hard limit. With 1.5 mm (more
/// than the pull-off) the switch is still closed after the pull-off: homing
/// fails rather than leave an axis on its switch.
///
/// Checked to fail: with the switch check at the end of `home_pulloff`
/// removed (the 1.5 mm case homes "fine" and its first move is a hard limit).
#[test]
fn homing_through_switch_hysteresis() {
    let mut io = FakeBoard::new();
    io.place([1500, 1200, 900, 0]);
    io.hysteresis = [20; 3];
    let mut r = Rig::boot(io);
    r.ok("G28");
    assert_eq!(r.xyz(), [100, 100, 100]);
    assert_eq!(r.io.transitions, [4, 4, 4]);
    r.ok("G0 X10 Y10 Z-10");
    assert_eq!(r.xyz(), [1000, 1000, 1000]);

    let mut io = FakeBoard::new();
    io.place([1500, 1200, 900, 0]);
    io.hysteresis = [0, 0, 150];
    let mut r = Rig::boot(io);
    let out = r.send("G28");
    assert!(out.contains("ALARM:homing failed"), "{out}");
    assert_eq!(runs(&r.io, 2, 0), [-900, 100], "failed right after the first pull-off");
    assert!(runs(&r.io, 1, 0).is_empty());
}

// ---- Tool change -----------------------------------------------------------

/// Steps per pocket pitch (3200 / 18).
const PITCH: f64 = 3200.0 / 18.0;

/// Carousel steps of pocket `p` (at `p + 3` pitches from the switch).
fn pocket_steps(p: u8) -> i64 {
    ((p as f64 + 3.0) * PITCH).round() as i64
}

/// Steps (absolute indices) from `from` at which Z physically arrives at
/// `z` coming down, i.e. the clamp/release moments at Z2.
fn arrivals(io: &FakeBoard, z: i64, from: usize) -> Vec<usize> {
    (from..io.steps.len()).filter(|&i| io.steps[i].axes & 4 != 0 && io.steps[i].phys[2] == z && io.steps[i].neg & 4 == 0).collect()
}

/// The EEPROM records of the changer.
fn records(io: &FakeBoard) -> ([u8; 5], [u8; 5]) {
    let s = EEPROM_STATE_ADDR as usize;
    let j = EEPROM_JOURNAL_ADDR as usize;
    (io.eeprom[s..s + 5].try_into().unwrap(), io.eeprom[j..j + 5].try_into().unwrap())
}

/// Home and stand at X10 Y5 Z−3 (Z 300 steps below the top).
fn ready_rig() -> Rig {
    let mut r = Rig::boot(FakeBoard::new());
    r.ok("G28");
    r.ok("G0 X10 Y5 Z-3");
    r
}

/// `T2` (NGC: only selects), `M6` (condition 1: empty spindle picks T2),
/// then with `$151=1` a `T5` alone changes at once (condition 2: T2 goes
/// back to pocket 2, T5 comes out of pocket 5). Checked on the board: the
/// spindle reaches Z2 at the station with the right pocket in front of it,
/// goes back to where it was at the travel height, the spindle stays off; and
/// in EEPROM: the journal is written before the first step of a change and
/// cleared after its last, the tool record follows each transfer, and the
/// final bytes decode to the tools' places.
///
/// Checked to fail: with `Action::EndJournal => clear_journal(io)` removed
/// from `atc::run::perform` (the journal stays active), and with the
/// `TurnToNew` row's `Do::TurnNew` made `Do::TurnOld` (the wrong pocket at
/// the clamp).
#[test]
fn a_tool_change_moves_through_the_station_and_keeps_its_journal() {
    let mut r = ready_rig();
    let before = r.xyz();
    assert_eq!(before, [1000, 500, 300]);

    let n0 = r.io.steps.len();
    let out = r.ok("T2");
    assert!(!out.contains("SelectTool"), "{out}");
    assert_eq!(r.io.steps.len(), n0, "T alone moves nothing under NGC");

    let log0 = r.io.eeprom_log.len();
    let out = r.ok("M6");
    assert!(out.contains("SelectTool:2\n") && out.contains("NowSelectedTool:2\n"), "{out}");
    // Condition 1: one trip down to Z2 (45 mm), at X1 23, Y point B 44,
    // pocket 2 in front of the spindle, then Y out to point A 28 at Z2.
    let down = arrivals(&r.io, 4500, n0);
    assert_eq!(down.len(), 1, "{down:?}");
    let at = r.io.steps[down[0]].phys;
    assert_eq!((at[0], at[1], at[3].rem_euclid(3200)), (2300, 4400, pocket_steps(2)));
    let lift = (down[0]..r.io.steps.len()).find(|&i| r.io.steps[i].neg & 4 != 0).unwrap();
    let y_moves: Vec<[i64; 4]> = r.io.steps[down[0]..lift].iter().map(|s| s.phys).collect();
    assert!(y_moves.iter().all(|p| p[2] == 4500), "Y out at Z2");
    assert_eq!(r.io.steps[lift].phys[1], 2800, "withdrawn to point A before lifting");
    assert_eq!(r.xyz(), [before[0], before[1], 100], "back over the start at the travel height");
    assert!(r.io.outputs.iter().all(|(_, o)| !matches!(o, Output::Spindle(d) if *d != 0)));

    // EEPROM: (blank) tool record, journal on before the first step, the
    // clamped state, journal off after the last step.
    let log = &r.io.eeprom_log[log0..];
    let jaddr = EEPROM_JOURNAL_ADDR;
    let starts: Vec<_> = log.iter().filter(|(_, a, _)| *a == jaddr).collect();
    assert_eq!(starts.len(), 2, "{log:?}");
    let on: [u8; 5] = starts[0].2.clone().try_into().unwrap();
    assert_eq!(Journal::from_bytes(&on), Some(Journal { from: 0, to: 2 }));
    assert_eq!(starts[0].0 as usize, n0, "journal on before the change's first step");
    assert_eq!(starts[1].0 as usize, r.io.steps.len(), "journal off after its last step");
    let (st, jb) = records(&r.io);
    assert_eq!(ToolState::from_bytes(&st), Some(ToolState { spindle: 2, occupied: ALL_POCKETS & !pocket_bit(2) }));
    assert_eq!(Journal::from_bytes(&jb), None);
    assert_eq!(jb, Journal::cleared(Journal::to_bytes(Some(Journal { from: 0, to: 2 }))));
    assert!(r.status().contains("|T:2>"));

    // Repetier's immediate T.
    r.ok("$151=1");
    let n1 = r.io.steps.len();
    let out = r.ok("T5");
    assert!(out.contains("SelectTool:5\n") && out.contains("NowSelectedTool:5\n"), "{out}");
    let down = arrivals(&r.io, 4500, n1);
    assert_eq!(down.len(), 2, "release T2, clamp T5: {down:?}");
    let rel = r.io.steps[down[0]].phys;
    let clamp = r.io.steps[down[1]].phys;
    assert_eq!((rel[0], rel[1], rel[3].rem_euclid(3200)), (2300, 4400, pocket_steps(2)), "T2 into pocket 2");
    assert_eq!((clamp[0], clamp[1], clamp[3].rem_euclid(3200)), (2300, 4400, pocket_steps(5)), "T5 from pocket 5");
    let (st, jb) = records(&r.io);
    let want = ToolState { spindle: 5, occupied: ALL_POCKETS & !pocket_bit(5) };
    assert_eq!(ToolState::from_bytes(&st), Some(want));
    assert_eq!(jb, Journal::cleared(Journal::to_bytes(Some(Journal { from: 2, to: 5 }))));
    assert_eq!(r.xyz(), [before[0], before[1], 100]);
}

/// An M112 in the middle of a change leaves the journal active; after a
/// power cycle the firmware reads it, says so, refuses motion until the
/// operator confirms the spindle with M61, which clears it; then the change
/// runs to the end.
///
/// Checked to fail: with the `BeginJournal` EEPROM write removed from
/// `atc::run::select` (nothing to resume from after the power cycle).
#[test]
fn an_interrupted_change_is_resumed_from_its_journal_after_a_power_cycle() {
    let mut r = ready_rig();
    let n0 = r.io.step_count();
    r.io.at(At::Step(n0 + 3000), Event::Estop);
    let out = r.send("T2 M6");
    assert!(out.contains("ALARM:emergency stop"), "{out}");
    assert_eq!(r.io.step_count(), n0 + 3000, "stopped at the M112");
    assert!(!r.io.drivers && r.io.spindle == 0);
    let (_, jb) = records(&r.io);
    assert_eq!(Journal::from_bytes(&jb), Some(Journal { from: 0, to: 2 }));

    // Power cycle: same EEPROM, motors where they stopped.
    let mut io = FakeBoard::new();
    io.eeprom = r.io.eeprom.clone();
    io.place(r.io.phys);
    let mut r = Rig::boot(io);
    let boot = r.io.take_out();
    assert!(boot.contains("echo:tool change T0->T2 interrupted: motion refused until M61 Q<tool in spindle>"), "{boot}");
    let n = r.io.step_count();
    assert!(r.refused("G28").contains("tool change interrupted"));
    assert_eq!(r.io.step_count(), n);
    r.ok("M61 Q0");
    let (st, jb) = records(&r.io);
    assert_eq!(Journal::from_bytes(&jb), None);
    assert_eq!(ToolState::from_bytes(&st), Some(ToolState { spindle: 0, occupied: ALL_POCKETS }));
    r.ok("G28");
    let out = r.ok("T2 M6");
    assert!(out.contains("NowSelectedTool:2"), "{out}");
    let (st, _) = records(&r.io);
    assert_eq!(ToolState::from_bytes(&st).map(|s| s.spindle), Some(2));
}

// ---- G37 -------------------------------------------------------------------

/// The tests' beam: X 3–7, Y 10.013, tip height 48.0047 mm below the Z
/// switch, 0.52 mm wide (as tests/toolsetter.rs).
const BEAM: Beam = Beam { x_mm: (3.0, 7.0), y_mm: 10.013, z_mm: 48.0047, width_mm: 0.52, steps_per_mm: 100.0 };
const T1: Tool = Tool { length_mm: 19.5, diameter_mm: 3.0 };
const T2: Tool = Tool { length_mm: 21.3371, diameter_mm: 3.175 };

/// The spindle Z step at which the beam breaks for `t` coming down.
fn trip_z(t: Tool) -> i64 {
    (BEAM.z_mm * 100.0 - t.length_mm * 100.0).ceil() as i64
}

/// The Y span (steps, trip to trip inclusive) of `t` across the beam.
fn y_span(t: Tool) -> i64 {
    let half = (t.diameter_mm + BEAM.width_mm) / 2.0 * 100.0;
    let (lo, hi) = ((BEAM.y_mm * 100.0 - half).ceil() as i64, (BEAM.y_mm * 100.0 + half).floor() as i64);
    hi - lo + 1
}

/// Homed, with T1 in the spindle and the setter calibrated on it
/// (`G37 L19.5 R1.5`); the calibration's reply.
fn setter_calibrated_on_t1() -> (Rig, String) {
    let mut io = FakeBoard::new();
    io.beam = Some(BEAM);
    let mut r = Rig::boot(io);
    r.ok("G28");
    r.ok("M61 Q1");
    r.io.tool = Some(T1);
    let cal = r.ok("G37 L19.5 R1.5");
    (r, cal)
}

/// Calibrate on T1 (L19.5 R1.5), then measure T2: G37 gives its length
/// and G37 D1 its diameter, exactly what the beam model implies (one
/// step resolution: the trip steps of T1 and T2 differ by 184 steps; the Y
/// spans by 18), stored in the tool table in EEPROM.
///
/// Checked to fail: with the beam width not subtracted from the span in
/// `Measure::result` (D 3.700), and with `toolsetter::run::probe` not
/// arming the ISR's probe watch (the seeks never trip: "beam never broke").
/// (Dropping the `+ 1` of the span, or taking the fast seek's trip, does
/// not change these results: the first cancels out through the
/// calibration, and the ISR stops on the trip step at either speed.)
#[test]
fn g37_measures_length_and_diameter_from_the_beam() {
    let (mut r, cal) = setter_calibrated_on_t1();
    assert!(cal.contains("[SETTER Z:-48.010 W:0.520]"), "{cal}");

    r.ok("M61 Q2");
    r.io.tool = Some(T2);
    let len_um = 19_500 + (trip_z(T1) - trip_z(T2)) * 10;
    assert_eq!(len_um, 21_340);
    let out = r.ok("G37");
    assert!(out.contains("[TOOL:2 L:21.340]\n"), "{out}");
    let d_um = 3_000 + (y_span(T2) - y_span(T1)) * 10;
    assert_eq!(d_um, 3_180);
    let out = r.ok("G37 D1");
    assert!(out.contains("[TOOL:2 L:21.340 D:3.180]\n"), "{out}");
    let a = EEPROM_TABLE_ADDR as usize;
    let tb = ToolTable::from_bytes(&r.io.eeprom[a..a + ToolTable::IMAGE_LEN].try_into().unwrap()).unwrap();
    assert_eq!((tb.length_um(2), tb.diameter_um(2)), (len_um as i32, d_um as u16));
    assert_eq!((tb.length_um(1), tb.diameter_um(1)), (19_500, 3_000));
    // Retracted to the travel height.
    assert_eq!(r.io.phys[2], 100);
}

/// A beam already broken: G37 is refused and nothing moves.
///
/// Checked to fail: with the `BeamBlocked` check removed from
/// `toolsetter::run::g37` (it seeks, with the beam "broken" all the way).
#[test]
fn g37_with_the_beam_blocked_is_refused_with_no_motion() {
    let (mut r, _) = setter_calibrated_on_t1();
    r.io.now(Event::Force(Input::ToolSetter, Some(true)));
    let n = r.io.step_count();
    assert!(r.refused("G37").contains("blocked at start"));
    assert_eq!(r.io.step_count(), n);
}

// ---- Alarms and hold ---------------------------------------------------------

/// A home switch closing during a move (X's, 500 steps into a cut): the
/// ISR stops on that very step and turns the spindle off in the same
/// interrupt; the main loop reports `ALARM:hard limit`, the machine is in
/// alarm and refuses motion until homed.
///
/// Checked to fail: with `limits` forced to 0 in `Machine::apply_watch`
/// (hard limits never armed: the move completes).
#[test]
fn a_switch_closing_mid_move_is_a_hard_limit_that_stops_at_once() {
    let mut r = ready_rig();
    r.ok("M3 S8000");
    assert!(r.io.spindle > 0);
    let n0 = r.io.step_count();
    r.io.at(At::Step(n0 + 500), Event::Force(Input::Home(0), Some(true)));
    r.send("G1 X40 F600");
    let hit = r.idle_until(200_000, |m, _| m.alarm.is_some());
    assert!(hit, "no alarm");
    let out = r.io.take_out();
    assert!(out.contains("ALARM:hard limit\n"), "{out}");
    // Let time pass: nothing moves any more.
    r.idle_until(4000, |_, _| false);
    assert_eq!(r.io.step_count(), n0 + 500, "stopped on the step the switch closed");
    let stop_cycle = r.io.steps.last().unwrap().cycle;
    let off = r.io.outputs.iter().find(|(_, o)| *o == Output::Spindle(0)).expect("spindle off");
    assert_eq!(off.0, stop_cycle, "spindle off in the same interrupt");
    assert_eq!(r.m.state, State::Alarm);
    assert!(r.refused("G0 X5").contains("alarm hard limit"));
    assert_eq!(r.io.step_count(), n0 + 500);
    // The switch opens again: homing recovers.
    r.io.now(Event::Force(Input::Home(0), None));
    r.ok("G28");
    assert_eq!(r.m.state, State::Idle);
}

/// `!` in the middle of a move: the axis slows down (step intervals grow)
/// and stops short of the target, nothing moves while held, `?` says Hold,
/// `~` resumes and the move ends exactly at its target.
///
/// Checked to fail: with `self.prep.hold()` removed from `Machine::idle`'s
/// hold branch (the move runs through the hold), and with the
/// `self.prep.resume()` of the resume branch removed (it never resumes).
#[test]
fn feed_hold_decelerates_to_a_stop_and_resume_ends_exactly_at_the_target() {
    let mut r = ready_rig();
    let n0 = r.io.step_count() as usize;
    r.io.at(At::Step(n0 as u64 + 1500), Event::Hold);
    r.send("G1 X40 F1200");
    let held = r.idle_until(200_000, |m, io| m.is_holding() && !stepping(io));
    assert!(held, "never came to rest");
    let stop = r.io.phys[0];
    assert!(stop > 1000 + 1500 && stop < 4000, "stopped short of the target: {stop}");
    // Step intervals: cruise at 1200 mm/min = 2000 steps/s (8000 cycles);
    // the last ones after the hold are at least twice as long.
    let xs: Vec<u64> = r.io.steps[n0..].iter().map(|s| s.cycle).collect();
    let dt: Vec<u64> = xs.windows(2).map(|w| w[1] - w[0]).collect();
    let cruise = dt[1400];
    assert!((7900..=8100).contains(&cruise), "cruise interval {cruise}");
    let last = *dt.last().unwrap();
    assert!(last >= 2 * cruise, "no deceleration: last interval {last} cycles");
    let after_hold = &dt[1500..];
    // (A shorter interval by more than 1 %: a speed-up.)
    let faster = after_hold.windows(2).filter(|w| w[1] + w[0] / 100 < w[0]).count();
    assert_eq!(faster, 0, "intervals only grow after the hold: {after_hold:?}");
    // Held: a second of main-loop turns, no step.
    let n = r.io.step_count();
    r.idle_until(4000, |_, _| false);
    assert_eq!(r.io.step_count(), n);
    assert!(r.status().starts_with("<Hold|"));
    // Resume: the rest of the move, to the step.
    r.io.now(Event::Resume);
    let done = r.idle_until(200_000, |m, io| m.motion_done(io) && !m.is_holding());
    assert!(done);
    assert_eq!(r.xyz(), [4000, 500, 300]);
    assert_eq!(r.counted(), [4000, 500, 300]);
    assert!(r.status().starts_with("<Idle|"));
}

/// grbl's feed override bytes in the middle of a move act on it at once:
/// 0x92 ×5 (50 %) halves the step rate within a few ms, 0x90 brings it
/// back, and the move still ends exactly at its target; queued moves follow
/// too, and `Ov:` reports it.
///
/// Checked to fail: with `apply_overrides` not called from `Machine::idle`
/// (the rate never changes), and with `set_overrides` changing the
/// percentage without re-planning the queued blocks (the executing move
/// keeps its speed).
#[test]
fn feed_override_bytes_change_the_speed_of_the_move_in_progress() {
    let mut r = ready_rig();
    let n0 = r.io.step_count() as usize;
    for k in 0..5 {
        r.io.at(At::Step(n0 as u64 + 1000 + k), Event::Override(0x92));
    }
    r.io.at(At::Step(n0 as u64 + 2500), Event::Override(0x90));
    r.send("G1 X40 F1200");
    r.send("G1 X44");
    let done = r.idle_until(400_000, |m, io| m.motion_done(io));
    assert!(done);
    let xs: Vec<u64> = r.io.steps[n0..].iter().map(|s| s.cycle).collect();
    let dt: Vec<u64> = xs.windows(2).map(|w| w[1] - w[0]).collect();
    // 1200 mm/min = 2000 steps/s (8000 cycles a step); at 50 %: 16000.
    assert!((7900..=8100).contains(&dt[900]), "cruise before: {}", dt[900]);
    // Reached within the motion already handed to the stepper (at most
    // 40 ms, `MAX_QUEUED_CYCLES`, plus the segment in progress: grbl's
    // segment buffer holds about as much) and the deceleration (15 ms).
    let slow = 1000 + dt[1000..2500].iter().position(|&d| d >= 15_800).expect("slowed to 50 %");
    let ms = (xs[slow] - xs[1000]) as f64 / 16_000.0;
    assert!(ms < 80.0, "50 % reached {ms:.1} ms after the bytes");
    assert!((15_800..=16_200).contains(&dt[2400]), "cruise at 50 %: {}", dt[2400]);
    assert!((7900..=8100).contains(&dt[2700]), "back at 100 %: {}", dt[2700]);
    assert_eq!(r.xyz(), [4400, 500, 300]);
    assert_eq!(r.counted(), [4400, 500, 300]);
    // The queued move after it ran at 100 % too, and M220 is the same value.
    r.ok("M220 S130");
    for _ in 0..12 {
        let st = r.status();
        if st.contains("|Ov:") {
            assert!(st.contains("|Ov:130,100,100"), "{st}");
            return;
        }
    }
    panic!("no Ov: field in 12 reports");
}

/// The stepper is producing steps (or has some queued).
fn stepping(io: &FakeBoard) -> bool {
    crate::machine::Stepper::stepper(io).busy
}

/// M112 in the middle of a move: the RX interrupt halts the stepper and
/// drops the drivers, spindle and coolant at once; the main loop reports
/// `ALARM:emergency stop`. Unlike other alarms homing does not clear it:
/// M999 first.
///
/// Checked to fail: with the `rt.estop` branch of `Machine::idle` removed
/// (no alarm: the machine believes it is still moving).
#[test]
fn m112_mid_move_stops_at_once_and_only_m999_clears_it() {
    let mut r = ready_rig();
    r.ok("M3 S8000");
    r.ok("M8");
    assert!(r.io.coolant);
    let n0 = r.io.step_count();
    r.io.at(At::Step(n0 + 700), Event::Estop);
    r.send("G1 X40 Y30 F900");
    assert!(r.idle_until(200_000, |m, _| m.alarm.is_some()), "no alarm");
    assert!(r.io.take_out().contains("ALARM:emergency stop\n"));
    r.idle_until(4000, |_, _| false);
    assert_eq!(r.io.step_count(), n0 + 700);
    assert_eq!((r.io.drivers, r.io.spindle, r.io.coolant), (false, 0, false));
    assert!(r.refused("G28").contains("alarm emergency stop"));
    assert_eq!(r.io.step_count(), n0 + 700);
    r.ok("M999");
    r.ok("G28");
    assert_eq!(r.xyz(), [100, 100, 100]);
}

/// The whole pipeline (planner, prep, splitter, Bresenham) on a 3-axis
/// move of one chunk (< 32767 events): every step is the nearest to the
/// straight line (within half a step: the Bresenham rounds), the move ends
/// exactly at its target, and the counted position is the physical one.
///
/// Checked to fail: with the Splitter's initial error `(events >> 1) - events`
/// made `-events` (the Bresenham truncates instead of rounding: up to 0.99
/// step behind the line). (Making `Chunk::tick` step one event late,
/// `e > 0` for `e >= 0`, stays within half a step here and is not caught.)
#[test]
fn a_three_axis_move_stays_within_half_a_step_of_its_line() {
    let mut r = ready_rig();
    let from = r.xyz();
    let n0 = r.io.steps.len();
    r.ok("G1 X37.77 Y12.34 Z-9.99 F2000");
    let to = r.xyz();
    assert_eq!(to, [3777, 1234, 999]);
    assert_eq!(r.counted(), [3777, 1234, 999]);
    let d: Vec<f64> = (0..3).map(|a| (to[a] - from[a]) as f64).collect();
    let n = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for s in &r.io.steps[n0..] {
        // Progress along the line from the dominant axis (X).
        let k = (s.phys[0] - from[0]) as f64 / n;
        for a in 1..3 {
            let ideal = from[a] as f64 + k * d[a];
            assert!((s.phys[a] as f64 - ideal).abs() <= 0.5 + 1e-9, "axis {a} at {:?}: ideal {ideal}", s.phys);
        }
    }
}

/// The carousel sensor unplugged: the change homes the carousel, turns a
/// revolution + 25 % (22.5 pitches, 4000 steps) without finding it, raises
/// `ALARM:carousel home switch not found` and stops there, with its
/// journal still active (the spindle must be checked) and the tool record
/// unchanged.
///
/// Checked to fail: with `Ok(false) => { m.raise(..) }` of
/// `atc::carousel::home` made `Ok(())` (the change carries on unhomed).
#[test]
fn a_carousel_switch_never_found_stops_the_change_with_its_journal_active() {
    let mut r = ready_rig();
    r.io.carousel_connected = false;
    let n0 = r.io.steps.len();
    let out = r.send("T2 M6");
    assert!(out.contains("ALARM:carousel home switch not found\n"), "{out}");
    assert!(out.contains("echo:tool change T0->T2 interrupted"), "{out}");
    assert!(!out.contains("NowSelectedTool"), "{out}");
    // The switch reads open at the start: no back-off, one whole seek.
    assert_eq!(runs(&r.io, 3, n0), [4000]);
    assert_eq!(r.io.phys[2], 4050, "stopped at Z1 in front of the magazine");
    let (st, jb) = records(&r.io);
    assert_eq!(Journal::from_bytes(&jb), Some(Journal { from: 0, to: 2 }));
    assert_eq!(ToolState::from_bytes(&st), Some(ToolState::FACTORY));
    assert_eq!(r.m.state, State::Alarm);
}

/// Ctrl-X (grbl's soft reset) in the middle of a move: the stepper halts
/// at once (the RX interrupt), the queue is dropped, grbl's banner goes out
/// and, since steps were being produced, `ALARM:reset while moving`.
///
/// Checked to fail: with `soft_reset`'s `moving` check removed (no alarm
/// after an abrupt stop).
#[test]
fn a_soft_reset_mid_move_halts_and_raises_reset_while_moving() {
    let mut r = ready_rig();
    let n0 = r.io.step_count();
    r.io.at(At::Step(n0 + 400), Event::Reset);
    r.send("G1 X40 F1200");
    assert!(r.idle_until(200_000, |m, _| m.alarm.is_some()), "no alarm");
    let out = r.io.take_out();
    assert!(out.contains("\r\nGrbl 1.1h ['$' for help]\r\n"), "{out}");
    assert!(out.contains("ALARM:reset while moving\n"), "{out}");
    r.idle_until(4000, |_, _| false);
    assert_eq!(r.io.step_count(), n0 + 400);
    assert!(r.m.motion_done(&r.io), "queue dropped");
    // The position kept is the one the motors are at.
    assert_eq!(r.counted(), [1000 + 400, 500, 300]);
}

/// G38.2 on the tool-setter input: the ISR stops on the step that breaks
/// the beam and `[PRB:…:1]` reports it (T2's tip, 21.3371 mm below the
/// spindle, reaches the beam 48.0047 mm below home at spindle step 2667);
/// G38.3 that does not trip reports `:0]` and is no error; G38.2 that does
/// not trip is (`probe failed` alarm).
///
/// Checked to fail: with `interp::probe` arming no probe watch
/// (`apply_watch(io, 0, false)`: the probe runs to its end).
#[test]
fn g38_probes_on_the_tool_setter_input_and_stops_on_the_trip_step() {
    let mut io = FakeBoard::new();
    io.beam = Some(BEAM);
    io.tool = Some(T2);
    let mut r = Rig::boot(io);
    r.ok("G28");
    r.ok("M61 Q2");
    r.ok("G0 X5 Y10.013");
    let out = r.ok("G38.2 Z-45 F300");
    assert!(out.contains("[PRB:5.000,10.010,-26.670:1]\n"), "{out}");
    assert_eq!(r.io.phys[2], trip_z(T2));
    assert_eq!(r.io.phys[2], 2667);
    r.ok("G0 Z-1");
    r.ok("G0 X30");
    let out = r.ok("G38.3 Z-20 F300");
    assert!(out.contains("[PRB:30.000,10.010,-20.000:0]\n"), "{out}");
    let out = r.refused("G38.2 Z-21 F300");
    assert!(out.contains("[PRB:30.000,10.010,-21.000:0]\n"), "{out}");
    assert_eq!(r.io.phys[2], 2100);
}

/// A long wait (a tool change, ~9 s of machine time) tells the host it is
/// alive: `busy:processing` every 2 s (M113's default), counted on the
/// board's clock from the start of the line.
///
/// Checked to fail: with `Machine::keepalive`'s interval test made
/// `>= every * 2` (a line every 4 s).
#[test]
fn a_long_wait_sends_busy_every_two_seconds() {
    let mut r = ready_rig();
    let t0 = r.io.ms();
    let out = r.ok("T2 M6");
    let took = r.io.ms() - t0;
    assert!(took > 8_000, "{took} ms");
    // One per whole 2 s from the start of the line (the last may fall
    // in the main-loop turn after the change ends).
    let busy = out.lines().filter(|l| *l == "busy:processing").count() as u32;
    assert!(busy == took / 2000 || busy + 1 == took / 2000, "{took} ms: {busy} busy lines");
}

// ---- Waits, pauses, aborts, locks -------------------------------------------

/// CPU cycles per millisecond of the board clock.
const MS: u64 = 16_000;

/// Board cycle of the last step in `steps[..end]` and of the first in `steps[end..]`.
fn gap(io: &FakeBoard, end: usize) -> (u64, u64) {
    (io.steps[end - 1].cycle, io.steps[end].cycle)
}

/// G4 P1.5 between two moves: the first ends, nothing moves for 1.5 s of
/// board time, then the second starts (within a few main-loop turns).
///
/// Checked to fail: with `interp::wait_ms` waiting `ms / 2.0`.
#[test]
fn g4_dwells_its_seconds_on_the_board_clock() {
    let mut r = ready_rig();
    r.send("G1 X20 F600");
    r.send("G4 P1.5");
    let end = r.io.steps.len();
    assert_eq!(r.io.phys[0], 2000, "the move ended before the dwell");
    r.ok("G1 X30 F600");
    let (a, b) = gap(&r.io, end);
    assert!(b - a >= 1500 * MS && b - a <= 1510 * MS, "dwell {} ms", (b - a) as f64 / MS as f64);
    assert_eq!(r.io.phys[0], 3000);
}

/// A dwell lasts at least its time whenever it starts: also when the
/// millisecond clock ticks right after the start (the first tick is then
/// almost no time), at every phase of the tick.
///
/// Checked to fail: with `wait_ms` ending when `ms` ticks have passed
/// (G4 S0.3 took 299.97 ms in tests/corpus.rs, reply included).
#[test]
fn a_dwell_is_never_shorter_than_its_time() {
    let mut r = ready_rig();
    for k in 0..32u64 {
        // The next dwell starts k/32 of a tick into a millisecond.
        let c = r.io.cycles;
        r.io.advance(MS - c % MS + k * MS / 32);
        let a = r.io.cycles;
        r.send("G4 P0.02");
        let b = r.io.cycles;
        assert!(b - a >= 20 * MS, "phase {k}/32: dwell {} ms", (b - a) as f64 / MS as f64);
        assert!(b - a <= 22 * MS, "phase {k}/32: dwell {} ms", (b - a) as f64 / MS as f64);
    }
}

/// M0 waits for `~`: a `?` meanwhile says Hold, nothing moves until the
/// resume (scripted 1 s later), then the program goes on.
///
/// Checked to fail: with `Machine::pause_until_resume` returning at once.
#[test]
fn m0_pauses_until_resume() {
    let mut r = ready_rig();
    r.send("G1 X20 F600");
    let t = r.io.ms();
    r.io.at(At::Ms(t + 2500), Event::Status);
    r.io.at(At::Ms(t + 3000), Event::Resume);
    let out = r.send("M0");
    assert!(out.contains("<Hold|"), "{out}");
    let end = r.io.steps.len();
    r.ok("G1 X30 F600");
    let (_, b) = gap(&r.io, end);
    assert!(b >= (t as u64 + 3000) * MS, "moved before the resume");
    assert_eq!(r.io.phys[0], 3000);
}

/// An abort (the menu's, or an SD job's) in the middle of a move:
/// decelerates like a hold, then drops everything queued (the next move
/// never starts), turns the spindle off, and the machine carries on from
/// where it stopped, with no alarm.
///
/// Checked to fail: with `self.planner.clear()` removed from
/// `Machine::finish_abort` (the queued Y move runs after the abort).
#[test]
fn an_abort_decelerates_drops_the_queue_and_stops_the_spindle() {
    let mut r = ready_rig();
    r.ok("M3 S8000");
    let n0 = r.io.step_count() as usize;
    r.io.at(At::Step(n0 as u64 + 1500), Event::Abort);
    r.send("G1 X40 F1200");
    r.send("G1 Y30");
    let stopped = r.idle_until(200_000, |m, io| !m.is_aborting() && m.motion_done(io));
    assert!(stopped);
    r.idle_until(4000, |_, _| false);
    let x = r.io.phys[0];
    assert!(x > 1000 + 1500 && x < 4000, "stopped short: {x}");
    assert!(runs(&r.io, 1, n0).is_empty(), "the queued Y move was dropped");
    let dt: Vec<u64> = r.io.steps[n0..].windows(2).map(|w| w[1].cycle - w[0].cycle).collect();
    assert!(*dt.last().unwrap() >= 2 * dt[1400], "decelerated");
    assert_eq!((r.io.spindle, r.m.alarm), (0, None));
    assert_eq!(r.counted(), [x as i32, 500, 300]);
    r.ok("G0 X5");
    assert_eq!(r.io.phys[0], 500);
}

/// After power-on (homing lock on), motion is refused and nothing moves
/// until G28 or M999; M999 unlocks at the unknown position.
///
/// Checked to fail: with `Machine::motion_allowed` always true.
#[test]
fn motion_before_homing_is_refused_until_homed_or_unlocked() {
    let mut r = Rig::boot(FakeBoard::new());
    let boot = r.io.take_out();
    assert!(boot.contains("echo:home (G28) before moving, or M999 to unlock"), "{boot}");
    let out = r.refused("G0 X5");
    assert!(out.contains("Error:not homed: home (G28) or unlock (M999) first, nothing moved"), "{out}");
    assert_eq!(r.io.step_count(), 0);
    r.ok("M999");
    r.ok("G0 X5");
    assert_eq!(r.io.phys[0], 2250 + 500);
}

/// G205 P0 homes the carousel (it starts on its switch: back off half a
/// pitch, seek, back off, slow seek; 0 is where the switch closes), G201
/// P0 X5 turns it to 5 pitches (889 steps), G203 reports it.
///
/// Checked to fail: with the first back-off (starting on the switch)
/// removed from `atc::carousel::home_steps` (the seek trips at once).
#[test]
fn g205_homes_the_carousel_and_g201_turns_it() {
    let mut r = ready_rig();
    let n0 = r.io.steps.len();
    r.ok("G205 P0");
    assert_eq!(runs(&r.io, 3, n0), [-89, 89, -89, 89]);
    assert_eq!((r.io.phys[3], r.io.pos[3]), (0, 0));
    r.ok("G201 P0 X5");
    assert_eq!((r.io.phys[3], r.io.pos[3]), (889, 889));
    let out = r.ok("G203 P0");
    assert!(out.contains("Motor0 Pos:5.000 Endstop Hit:0\n"), "{out}");
    assert!(runs(&r.io, 0, n0).is_empty() && runs(&r.io, 1, n0).is_empty() && runs(&r.io, 2, n0).is_empty());
}

/// The length G37 measures becomes the tool offset (auto offset, the
/// default): the same program line `G1 Z-40` puts each tool's tip 40 mm
/// below home, so the spindle stands higher by the length difference.
///
/// Checked to fail: with `apply_offset` removed from the end of
/// `toolsetter::run::store` (T2 cuts with the offset M61 gave it: none).
#[test]
fn the_measured_length_becomes_the_tool_offset() {
    let (mut r, _) = setter_calibrated_on_t1();
    r.ok("G0 X30 Y20");
    r.ok("G1 Z-40 F300");
    assert_eq!(r.io.phys[2], 4000 - 1950, "T1's tip at 40 mm");
    r.ok("G0 Z-30");
    r.ok("M61 Q2");
    r.io.tool = Some(T2);
    r.ok("G37");
    r.ok("G0 X30 Y20");
    r.ok("G1 Z-40 F300");
    assert_eq!(r.io.phys[2], 4000 - 2134, "T2's tip at 40 mm (length 21.34)");
}

/// M112 during homing (Y's seek): everything stops on that step, the
/// cycle ends in `ALARM:emergency stop` with nothing homed, and X never
/// moves.
///
/// Checked to fail: with `Machine::wait_step` not failing on an alarm
/// (`if self.alarm.is_some()` → `if false`: homing carries on after the M112).
#[test]
fn m112_during_homing_stops_the_cycle() {
    let mut io = FakeBoard::new();
    io.place([700, 800, 900, 0]);
    let mut r = Rig::boot(io);
    // Z's cycle is 900 + 300 steps; 200 more are Y's fast seek.
    r.io.at(At::Step(1400), Event::Estop);
    let out = r.send("G28");
    assert!(out.contains("ALARM:emergency stop\n"), "{out}");
    assert!(out.contains("Error:alarm emergency stop"), "{out}");
    r.idle_until(4000, |_, _| false);
    assert_eq!(r.io.step_count(), 1400);
    assert_eq!(runs(&r.io, 1, 0), [-200]);
    assert!(runs(&r.io, 0, 0).is_empty());
    assert_eq!((r.m.homed, r.m.state), (0, State::Alarm));
}

/// `!` in the middle of a tool change (on the way to the station): the
/// change holds (no step for a second), `~` resumes it, and it completes
/// exactly as without the hold: the clamp at the station with pocket 2,
/// the records, back over the start.
///
/// Checked to fail: with the resume branch of `Machine::idle` ignoring
/// `~` while the state is `Tool` (`if rt.resume && self.holding &&
/// self.state != State::Tool`: the change never resumes).
#[test]
fn a_feed_hold_pauses_a_tool_change_and_resume_completes_it() {
    let mut r = ready_rig();
    let n0 = r.io.step_count();
    r.io.at(At::Step(n0 + 1000), Event::Hold);
    let t = r.io.ms();
    r.io.at(At::Ms(t + 3000), Event::Resume);
    let out = r.ok("T2 M6");
    assert!(out.contains("NowSelectedTool:2\n"), "{out}");
    // The hold: a gap of over a second in the steps, after step 1000 and a deceleration.
    let s = &r.io.steps[n0 as usize..];
    let longest = s.windows(2).map(|w| w[1].cycle - w[0].cycle).max().unwrap();
    assert!(longest > 1000 * MS, "no pause: longest gap {} ms", longest / MS);
    let down = arrivals(&r.io, 4500, n0 as usize);
    assert_eq!(down.len(), 1);
    let at = r.io.steps[down[0]].phys;
    assert_eq!((at[0], at[1], at[3].rem_euclid(3200)), (2300, 4400, pocket_steps(2)));
    let (st, jb) = records(&r.io);
    assert_eq!(ToolState::from_bytes(&st).map(|s| s.spindle), Some(2));
    assert_eq!(Journal::from_bytes(&jb), None);
    assert_eq!(r.xyz(), [1000, 500, 100]);
}
