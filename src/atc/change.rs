//! The tool-change sequence of thesis §5.3 (Conditions 1–3, docs/SPEC.md §7) as a
//! state machine whose transitions are a table.
//!
//! Pure: it never moves anything. It hands out one [`Action`] at a time; the
//! executor (`machine::toolchange`) performs it through the planner and answers with an
//! [`Event`]. Host tests drive it with a fake executor.
//!
//! [`TABLE`] lists every state in order with the condition under which it
//! runs and what it does. From a state, the next state is the next row whose
//! condition holds; a failed action ends the change in [`Action::Abort`].
//!
//! | condition | spindle | asked | rows that run |
//! |---|---|---|---|
//! | 1: pick | empty | n > 0 | common, `TurnToNew`, `InsertNew`, `ClampNew`, `NewInSpindle`, `WithdrawNew` |
//! | 2: change | m > 0 | n > 0 | common, the `…Old` rows, then `TurnToNew`, `ClampNew`, `NewInSpindle`, `WithdrawNew` |
//! | 3: empty | m > 0 | 0 | common, the `…Old` rows, `WithdrawEmpty` |
//!
//! "Common" is the spindle off, the journal, the way to the station and
//! (if needed) carousel homing at the start, and the way back at the end.

use super::tools::{Journal, ToolState};
use super::{pocket_position, Fault, Station};

/// One state of a tool change (one row of [`TABLE`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    /// Turn the spindle off (M5).
    SpindleOff,
    /// Write the "change in progress" record.
    BeginJournal,
    /// Rapid Z up to the travel height.
    LiftToSafe,
    /// Rapid to X1, Y point A.
    ToStation,
    /// Rapid down to Z1, in front of the magazine.
    DownToZ1,
    /// Home the carousel (only if it is not homed).
    HomeCarousel,
    /// Turn the old tool's (empty) pocket to the station.
    TurnToOld,
    /// Y to point B at F800: the old tool slides into its pocket.
    InsertOld,
    /// Z down to Z2: the tool is pushed home and released.
    ReleaseOld,
    /// Record: the old tool is in its pocket, the spindle is empty.
    OldInPocket,
    /// Z up to Z1, leaving the old tool in its pocket.
    LiftFromOld,
    /// Turn the new tool's pocket to the station.
    TurnToNew,
    /// Condition 1 only: Y to point B at F800, above the new tool.
    InsertNew,
    /// Z down to Z2 at F200: the spindle clamps the new tool.
    ClampNew,
    /// Record: the new tool is in the spindle, its pocket empty.
    NewInSpindle,
    /// Y out to point A at F1000, pulling the new tool out of its pocket.
    WithdrawNew,
    /// T0: Y out to point A with the spindle empty.
    WithdrawEmpty,
    /// Rapid Z up to the travel height.
    LiftAfter,
    /// Rapid back to the X/Y held before the change.
    ReturnXY,
    /// Clear the "change in progress" record.
    EndJournal,
}

/// When a row runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum When {
    Always,
    /// A tool is in the spindle at the start (conditions 2 and 3).
    Old,
    /// A tool is asked for (conditions 1 and 2).
    New,
    /// Condition 1: no tool at the start, one asked for.
    NewOnly,
    /// Condition 3: T0.
    NoNew,
    /// The carousel has not been homed.
    CarouselUnhomed,
}

/// A Z or Y target of the station (thesis Table 8).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Point {
    /// The travel height (near the top: Z grows downward).
    ZSafe,
    Z1,
    Z2,
    YA,
    YB,
}

/// A feed of the sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feed {
    Rapid,
    /// Y in, F800.
    YIn,
    /// Z down to clamp, F200.
    ZClamp,
    /// Z down to release and back up, F1000.
    ZRelease,
    /// Y out, F1000.
    YOut,
}

/// What a row does, as data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Do {
    SpindleOff,
    BeginJournal,
    /// Move one axis to a station point.
    To(Point, Feed),
    /// Rapid to X1, Y point A.
    Station,
    /// Rapid to the saved X/Y.
    Back,
    HomeCarousel,
    TurnOld,
    TurnNew,
    /// Store the tool state after the release.
    StoreReleased,
    /// Store the tool state after the clamp.
    StoreClamped,
    EndJournal,
}

/// One row: a state, when it runs, what it does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Row {
    pub state: State,
    pub when: When,
    pub act: Do,
}

const fn row(state: State, when: When, act: Do) -> Row {
    Row { state, when, act }
}

/// The tool change, in order (thesis §5.3, docs/SPEC.md §7 steps 1–6).
pub const TABLE: [Row; 20] = [
    row(State::SpindleOff, When::Always, Do::SpindleOff),
    row(State::BeginJournal, When::Always, Do::BeginJournal),
    row(State::LiftToSafe, When::Always, Do::To(Point::ZSafe, Feed::Rapid)),
    row(State::ToStation, When::Always, Do::Station),
    row(State::DownToZ1, When::Always, Do::To(Point::Z1, Feed::Rapid)),
    row(State::HomeCarousel, When::CarouselUnhomed, Do::HomeCarousel),
    row(State::TurnToOld, When::Old, Do::TurnOld),
    row(State::InsertOld, When::Old, Do::To(Point::YB, Feed::YIn)),
    row(State::ReleaseOld, When::Old, Do::To(Point::Z2, Feed::ZRelease)),
    row(State::OldInPocket, When::Old, Do::StoreReleased),
    row(State::LiftFromOld, When::Old, Do::To(Point::Z1, Feed::ZRelease)),
    row(State::TurnToNew, When::New, Do::TurnNew),
    row(State::InsertNew, When::NewOnly, Do::To(Point::YB, Feed::YIn)),
    row(State::ClampNew, When::New, Do::To(Point::Z2, Feed::ZClamp)),
    row(State::NewInSpindle, When::New, Do::StoreClamped),
    row(State::WithdrawNew, When::New, Do::To(Point::YA, Feed::YOut)),
    row(State::WithdrawEmpty, When::NoNew, Do::To(Point::YA, Feed::YOut)),
    row(State::LiftAfter, When::Always, Do::To(Point::ZSafe, Feed::Rapid)),
    row(State::ReturnXY, When::Always, Do::Back),
    row(State::EndJournal, When::Always, Do::EndJournal),
];

in_flash! {
    /// [`TABLE`] kept in flash: used at run time, a `const` table would be
    /// copied into RAM at boot on AVR (80 bytes).
    static TABLE_IN_FLASH: [Row; TABLE.len()] = TABLE;
}

/// Row `i` of [`TABLE`], read from flash.
fn row_at(i: usize) -> Option<Row> {
    TABLE_IN_FLASH.row(i)
}

/// What the executor is asked to do next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Spindle off (M5).
    SpindleOff,
    /// Write the "change in progress" record.
    BeginJournal(Journal),
    /// Move to machine mm; `None` keeps that axis. Feed in mm/min, `None` = rapid.
    Move { xyz: [Option<f32>; 3], feed_mm_per_min: Option<f32> },
    /// Home the carousel (G205 P0 S0 E0).
    HomeCarousel,
    /// Turn the carousel to this position, pitches from home.
    Turn { position: f32 },
    /// A tool changed place: store this state (and its EEPROM record).
    Store(ToolState),
    /// Clear the "change in progress" record.
    EndJournal,
    /// The change is complete.
    Done,
    /// The change stopped on a fault; the machine stays where it is.
    Abort(Fault),
}

/// The executor's answer to an action.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// The action completed.
    Done,
    /// The action failed.
    Failed(Fault),
}

/// Everything a change needs to know when it is asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// Tool asked for (the T word).
    pub to: u16,
    /// Where the tools are.
    pub tools: ToolState,
    /// X, Y and Z are homed.
    pub xyz_homed: bool,
    /// The carousel is homed.
    pub carousel_homed: bool,
    /// Commanded X, Y before the change, machine mm.
    pub xy_mm: [f32; 2],
    /// Travel of X, Y, Z, mm (soft limits).
    pub travel_mm: [f32; 3],
}

/// A running tool change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Change {
    from: u8,
    to: u8,
    carousel_homed: bool,
    xy_mm: [f32; 2],
    tools: ToolState,
    /// Index of the current row in [`TABLE`]; `TABLE.len()` when done.
    at: u8,
    /// Set once the change ended.
    result: Option<Result<(), Fault>>,
}

impl Change {
    /// Check a request before anything moves. `Ok(None)`: the tool asked
    /// for is already in the spindle, nothing to do.
    pub fn new(r: &Request, s: &Station) -> Result<Option<Change>, Fault> {
        if r.to as usize > super::tools::N_POCKETS {
            return Err(Fault::ToolRange);
        }
        let to = r.to as u8;
        let from = r.tools.spindle;
        if to == from {
            return Ok(None);
        }
        if !r.xyz_homed {
            return Err(Fault::NotHomed);
        }
        if from != 0 && r.tools.pocket_full(from) {
            return Err(Fault::ReturnPocketFull);
        }
        if to != 0 && !r.tools.pocket_full(to) {
            return Err(Fault::PocketEmpty);
        }
        let inside = |v: f32, axis: usize| v >= 0.0 && v <= r.travel_mm[axis];
        let ok = s.outside(&r.travel_mm).is_none() && inside(r.xy_mm[0], 0) && inside(r.xy_mm[1], 1);
        if !ok {
            return Err(Fault::SoftLimit);
        }
        Ok(Some(Change { from, to, carousel_homed: r.carousel_homed, xy_mm: r.xy_mm, tools: r.tools, at: 0, result: None }))
    }

    /// Tool in the spindle when the change started.
    pub fn from(&self) -> u8 {
        self.from
    }

    /// Tool asked for.
    pub fn to(&self) -> u8 {
        self.to
    }

    /// The current state; `None` once the change ended.
    pub fn state(&self) -> Option<State> {
        if self.result.is_some() {
            None
        } else {
            row_at(self.at as usize).map(|r| r.state)
        }
    }

    /// How it ended: `None` while running.
    pub fn result(&self) -> Option<Result<(), Fault>> {
        self.result
    }

    /// The tool state as far as the change got.
    pub fn tools(&self) -> ToolState {
        self.tools
    }

    fn applies(&self, w: When) -> bool {
        let old = self.from != 0;
        let new = self.to != 0;
        match w {
            When::Always => true,
            When::Old => old,
            When::New => new,
            When::NewOnly => new && !old,
            When::NoNew => !new,
            When::CarouselUnhomed => !self.carousel_homed,
        }
    }

    /// First row at or after `i` that applies.
    fn next_row(&self, mut i: usize) -> usize {
        while i < TABLE.len() && !row_at(i).is_some_and(|r| self.applies(r.when)) {
            i += 1;
        }
        i
    }

    /// The first action.
    pub fn start(&mut self, s: &Station) -> Action {
        self.at = self.next_row(0) as u8;
        self.action(s)
    }

    /// Feed the outcome of the last action; returns the next one.
    pub fn step(&mut self, ev: Event, s: &Station) -> Action {
        if let Some(r) = self.result {
            return match r {
                Ok(()) => Action::Done,
                Err(f) => Action::Abort(f),
            };
        }
        match ev {
            Event::Failed(f) => {
                self.result = Some(Err(f));
                Action::Abort(f)
            }
            Event::Done => {
                match row_at(self.at as usize).map(|r| r.act) {
                    Some(Do::StoreReleased) => self.tools = self.tools.released(),
                    Some(Do::StoreClamped) => self.tools = self.tools.clamped(self.to),
                    Some(Do::HomeCarousel) => self.carousel_homed = true,
                    _ => {}
                }
                self.at = self.next_row(self.at as usize + 1) as u8;
                self.action(s)
            }
        }
    }

    /// The action of the current row.
    fn action(&mut self, s: &Station) -> Action {
        let Some(row) = row_at(self.at as usize) else {
            self.result = Some(Ok(()));
            return Action::Done;
        };
        let mv = |axis: usize, v: f32, feed: Option<f32>| {
            let mut xyz = [None; 3];
            xyz[axis] = Some(v);
            Action::Move { xyz, feed_mm_per_min: feed }
        };
        match row.act {
            Do::SpindleOff => Action::SpindleOff,
            Do::BeginJournal => Action::BeginJournal(Journal { from: self.from, to: self.to }),
            Do::To(p, f) => {
                let feed = match f {
                    Feed::Rapid => None,
                    Feed::YIn => Some(s.feed_y_in),
                    Feed::ZClamp => Some(s.feed_z_clamp),
                    Feed::ZRelease => Some(s.feed_z_release),
                    Feed::YOut => Some(s.feed_y_out),
                };
                match p {
                    Point::ZSafe => mv(2, s.z_safe, feed),
                    Point::Z1 => mv(2, s.z1, feed),
                    Point::Z2 => mv(2, s.z2, feed),
                    Point::YA => mv(1, s.y_a, feed),
                    Point::YB => mv(1, s.y_b, feed),
                }
            }
            Do::Station => Action::Move { xyz: [Some(s.x1), Some(s.y_a), None], feed_mm_per_min: None },
            Do::Back => Action::Move { xyz: [Some(self.xy_mm[0]), Some(self.xy_mm[1]), None], feed_mm_per_min: None },
            Do::HomeCarousel => Action::HomeCarousel,
            Do::TurnOld => Action::Turn { position: pocket_position(self.from, s.pocket_offset) },
            Do::TurnNew => Action::Turn { position: pocket_position(self.to, s.pocket_offset) },
            Do::StoreReleased => Action::Store(self.tools.released()),
            Do::StoreClamped => Action::Store(self.tools.clamped(self.to)),
            Do::EndJournal => Action::EndJournal,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tools::{pocket_bit, ALL_POCKETS};
    use super::*;

    fn request(spindle: u8, to: u16) -> Request {
        Request {
            to,
            tools: ToolState { spindle, occupied: ALL_POCKETS & !pocket_bit(spindle) },
            xyz_homed: true,
            carousel_homed: false,
            xy_mm: [10.0, 5.0],
            travel_mm: [45.0; 3],
        }
    }

    /// Run a change with an executor that succeeds at everything; returns
    /// the states visited and the actions handed out.
    fn run(r: &Request) -> (Vec<State>, Vec<Action>, Change) {
        let mut c = Change::new(r, &Station::THESIS).unwrap().expect("a change");
        let mut states = Vec::new();
        let mut actions = Vec::new();
        let mut a = c.start(&Station::THESIS);
        while !matches!(a, Action::Done | Action::Abort(_)) {
            states.push(c.state().unwrap());
            actions.push(a);
            a = c.step(Event::Done, &Station::THESIS);
        }
        assert_eq!(a, Action::Done);
        (states, actions, c)
    }

    fn z(v: f32, f: Option<f32>) -> Action {
        Action::Move { xyz: [None, None, Some(v)], feed_mm_per_min: f }
    }

    fn y(v: f32, f: Option<f32>) -> Action {
        Action::Move { xyz: [None, Some(v), None], feed_mm_per_min: f }
    }

    #[test]
    fn condition_1_pick_with_an_empty_spindle() {
        let (states, actions, c) = run(&request(0, 5));
        use State::*;
        assert_eq!(
            states,
            [
                SpindleOff,
                BeginJournal,
                LiftToSafe,
                ToStation,
                DownToZ1,
                HomeCarousel,
                TurnToNew,
                InsertNew,
                ClampNew,
                NewInSpindle,
                WithdrawNew,
                LiftAfter,
                ReturnXY,
                EndJournal
            ]
        );
        assert_eq!(actions[0], Action::SpindleOff);
        assert_eq!(actions[1], Action::BeginJournal(Journal { from: 0, to: 5 }));
        assert_eq!(actions[2], z(1.0, None));
        assert_eq!(actions[3], Action::Move { xyz: [Some(23.0), Some(28.0), None], feed_mm_per_min: None });
        assert_eq!(actions[4], z(40.5, None));
        assert_eq!(actions[6], Action::Turn { position: 8.0 });
        assert_eq!(actions[7], y(44.0, Some(800.0)));
        assert_eq!(actions[8], z(45.0, Some(200.0)));
        assert_eq!(actions[9], Action::Store(ToolState { spindle: 5, occupied: ALL_POCKETS & !pocket_bit(5) }));
        assert_eq!(actions[10], y(28.0, Some(1000.0)));
        assert_eq!(actions[12], Action::Move { xyz: [Some(10.0), Some(5.0), None], feed_mm_per_min: None });
        assert_eq!(actions[13], Action::EndJournal);
        assert_eq!(c.tools().spindle, 5);
        assert_eq!(c.result(), Some(Ok(())));
        assert_eq!(c.state(), None);
    }

    #[test]
    fn condition_2_change_returns_the_old_tool_first() {
        let (states, actions, c) = run(&request(3, 7));
        use State::*;
        assert_eq!(
            states,
            [
                SpindleOff,
                BeginJournal,
                LiftToSafe,
                ToStation,
                DownToZ1,
                HomeCarousel,
                TurnToOld,
                InsertOld,
                ReleaseOld,
                OldInPocket,
                LiftFromOld,
                TurnToNew,
                ClampNew,
                NewInSpindle,
                WithdrawNew,
                LiftAfter,
                ReturnXY,
                EndJournal
            ]
        );
        assert_eq!(actions[6], Action::Turn { position: 6.0 });
        assert_eq!(actions[7], y(44.0, Some(800.0)));
        assert_eq!(actions[8], z(45.0, Some(1000.0)));
        assert_eq!(actions[9], Action::Store(ToolState { spindle: 0, occupied: ALL_POCKETS }));
        assert_eq!(actions[10], z(40.5, Some(1000.0)));
        assert_eq!(actions[11], Action::Turn { position: 10.0 });
        assert_eq!(actions[12], z(45.0, Some(200.0)));
        assert_eq!(actions[13], Action::Store(ToolState { spindle: 7, occupied: ALL_POCKETS & !pocket_bit(7) }));
        assert_eq!(c.tools().spindle, 7);
    }

    #[test]
    fn condition_3_t0_returns_the_tool_and_leaves_the_spindle_empty() {
        let (states, actions, c) = run(&request(12, 0));
        use State::*;
        assert_eq!(
            states,
            [
                SpindleOff,
                BeginJournal,
                LiftToSafe,
                ToStation,
                DownToZ1,
                HomeCarousel,
                TurnToOld,
                InsertOld,
                ReleaseOld,
                OldInPocket,
                LiftFromOld,
                WithdrawEmpty,
                LiftAfter,
                ReturnXY,
                EndJournal
            ]
        );
        assert_eq!(actions[6], Action::Turn { position: 15.0 });
        assert_eq!(actions[11], y(28.0, Some(1000.0)));
        assert_eq!(c.tools(), ToolState { spindle: 0, occupied: ALL_POCKETS });
    }

    #[test]
    fn a_homed_carousel_is_not_homed_again() {
        let mut r = request(0, 1);
        r.carousel_homed = true;
        let (states, _, _) = run(&r);
        assert!(!states.contains(&State::HomeCarousel));
    }

    #[test]
    fn the_tool_already_in_the_spindle_needs_no_change() {
        assert_eq!(Change::new(&request(7, 7), &Station::THESIS), Ok(None));
        assert_eq!(Change::new(&request(0, 0), &Station::THESIS), Ok(None));
    }

    #[test]
    fn requests_that_cannot_run_are_refused_before_anything_moves() {
        assert_eq!(Change::new(&request(0, 13), &Station::THESIS), Err(Fault::ToolRange));
        let mut r = request(0, 2);
        r.xyz_homed = false;
        assert_eq!(Change::new(&r, &Station::THESIS), Err(Fault::NotHomed));
        let mut r = request(0, 2);
        r.tools.occupied &= !pocket_bit(2);
        assert_eq!(Change::new(&r, &Station::THESIS), Err(Fault::PocketEmpty));
        let mut r = request(4, 2);
        r.tools.occupied |= pocket_bit(4);
        assert_eq!(Change::new(&r, &Station::THESIS), Err(Fault::ReturnPocketFull));
        let mut r = request(0, 2);
        r.travel_mm[1] = 40.0; // Y point B (44) is outside
        assert_eq!(Change::new(&r, &Station::THESIS), Err(Fault::SoftLimit));
        let mut r = request(0, 2);
        r.xy_mm = [-1.0, 0.0];
        assert_eq!(Change::new(&r, &Station::THESIS), Err(Fault::SoftLimit));
    }

    /// Every transition into `Abort`: fail each action of each condition in
    /// turn and check the change stops there with the tool state as far as
    /// it got (what the EEPROM then holds).
    #[test]
    fn a_fault_at_any_state_aborts_with_the_tool_state_so_far() {
        for (from, to) in [(0u8, 5u16), (3, 7), (12, 0)] {
            let r = request(from, to);
            let (states, _, _) = run(&r);
            for fail_at in 0..states.len() {
                let mut c = Change::new(&r, &Station::THESIS).unwrap().unwrap();
                let mut a = c.start(&Station::THESIS);
                for _ in 0..fail_at {
                    a = c.step(Event::Done, &Station::THESIS);
                }
                assert!(!matches!(a, Action::Done | Action::Abort(_)));
                let failed_state = c.state().unwrap();
                assert_eq!(failed_state, states[fail_at]);
                assert_eq!(c.step(Event::Failed(Fault::Stopped), &Station::THESIS), Action::Abort(Fault::Stopped));
                assert_eq!(c.result(), Some(Err(Fault::Stopped)));
                assert_eq!(c.state(), None);
                // Further events do not restart it.
                assert_eq!(c.step(Event::Done, &Station::THESIS), Action::Abort(Fault::Stopped));
                // The tool state reflects exactly the stores that completed.
                let released = states[..fail_at].contains(&State::OldInPocket);
                let clamped = states[..fail_at].contains(&State::NewInSpindle);
                let expect = match (released, clamped) {
                    (_, true) => to as u8,
                    (true, false) => 0,
                    (false, false) => from,
                };
                assert_eq!(c.tools().spindle, expect, "{from}->{to} failing at {failed_state:?}");
                assert!(c.tools().is_consistent());
            }
        }
    }

    #[test]
    fn table_rows_are_in_state_order_and_unique() {
        for (i, r) in TABLE.iter().enumerate() {
            assert!(TABLE[i + 1..].iter().all(|o| o.state != r.state), "{:?} twice", r.state);
        }
        // Spindle off comes before any motion, the journal before the first move.
        assert_eq!(TABLE[0].act, Do::SpindleOff);
        assert_eq!(TABLE[1].act, Do::BeginJournal);
        assert_eq!(TABLE[TABLE.len() - 1].act, Do::EndJournal);
    }
}
