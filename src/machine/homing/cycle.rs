//! The homing cycle of G28 / `$H` (docs/SPEC.md §6) as a state machine
//! whose transitions are a table, like the tool change
//! (`crate::atc::change`).
//!
//! Pure: it never moves anything and names nothing of the controller. It
//! hands out one [`Action`] at a time; the runner (`machine::homing`)
//! performs it through the planner and answers with an [`Event`]. Host
//! tests drive it with a fake runner.
//!
//! [`TABLE`] lists the states of one axis in order with the condition
//! under which each runs and what it does. The axes of the mask are homed
//! one after the other in the order Z, Y, X (Z first: the tool clears the
//! work before anything moves sideways); within an axis the next state is
//! the next row whose condition holds. A seek that finds no switch, or a
//! pull-off that leaves the switch closed, ends the cycle in
//! [`Action::Fail`] (the homing alarm); an action stopped on its way (an
//! alarm, an abort, a soft reset) ends it in [`Action::Stop`].
//!
//! | state | runs | does |
//! |---|---|---|
//! | `Unhome` | always | the axis' position is unknown from here on |
//! | `ReadSwitch` | always | read its switch |
//! | `LeaveSwitch` | the switch was closed | pull off at the locate feed (fails if it stays closed) |
//! | `FastSeek` | always | seek the switch at the seek feed, up to the travel + 10 % |
//! | `BackOff` | always | pull off at the seek feed |
//! | `SlowSeek` | always | seek at the locate feed, up to twice the pull-off: position 0 is where it trips |
//! | `FinalPullOff` | always | pull off at the locate feed (counted: position = pull-off) |
//! | `Homed` | always | the axis' position is known |

/// Axes G28 homes (X, Y, Z).
pub const N_LINEAR: u8 = 3;

/// The `i`-th axis to home: Z, Y, X (computed, not a table: a `const`
/// array indexed at run time would be copied into RAM on AVR).
fn nth_axis(i: u8) -> Option<u8> {
    (i < N_LINEAR).then(|| N_LINEAR - 1 - i)
}

/// Shortest pull-off, mm: a switch needs some travel to let go.
pub const MIN_PULLOFF_MM: f32 = 0.1;

/// Fast seek distance: the travel and this much more (10 %).
pub const SEEK_MARGIN: f32 = 1.1;

/// One state of an axis' homing (one row of [`TABLE`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    /// Clear the axis' homed bit.
    Unhome,
    /// Read the axis' switch.
    ReadSwitch,
    /// Starting on the switch: move off it first.
    LeaveSwitch,
    /// Seek the switch fast, up to the travel + 10 %.
    FastSeek,
    /// Back off the switch.
    BackOff,
    /// Seek the switch slowly: position 0 is where it trips.
    SlowSeek,
    /// Back off the switch again; the axis ends here.
    FinalPullOff,
    /// Set the axis' homed bit.
    Homed,
}

/// When a row runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum When {
    Always,
    /// The axis' switch read closed in `ReadSwitch`.
    OnSwitch,
}

/// A feed of the cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feed {
    /// `$25`, the homing seek feed.
    Seek,
    /// `$24`, the homing (locate) feed.
    Locate,
}

/// How far a seek goes at most.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reach {
    /// The axis' travel + 10 %.
    Travel,
    /// Twice the pull-off.
    TwoPullOffs,
}

/// What a row does, as data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Do {
    Unhome,
    ReadSwitch,
    /// Move away from the switch by the pull-off, then read it.
    PullOff(Feed),
    /// Move toward the switch until it trips.
    Seek(Reach, Feed),
    Homed,
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

/// One axis' homing, in order.
pub const TABLE: [Row; 8] = [
    row(State::Unhome, When::Always, Do::Unhome),
    row(State::ReadSwitch, When::Always, Do::ReadSwitch),
    row(State::LeaveSwitch, When::OnSwitch, Do::PullOff(Feed::Locate)),
    row(State::FastSeek, When::Always, Do::Seek(Reach::Travel, Feed::Seek)),
    row(State::BackOff, When::Always, Do::PullOff(Feed::Seek)),
    row(State::SlowSeek, When::Always, Do::Seek(Reach::TwoPullOffs, Feed::Locate)),
    row(State::FinalPullOff, When::Always, Do::PullOff(Feed::Locate)),
    row(State::Homed, When::Always, Do::Homed),
];

in_flash! {
    /// [`TABLE`] kept in flash: a `const` table used at run time would be
    /// copied into RAM at boot on AVR.
    static TABLE_IN_FLASH: [Row; TABLE.len()] = TABLE;
}

/// Row `i` of [`TABLE`], read from flash.
fn row_at(i: usize) -> Option<Row> {
    TABLE_IN_FLASH.row(i)
}

/// What the runner is asked to do next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// The axis' position is unknown: clear its homed bit. Answer `Done`.
    Unhome { axis: u8 },
    /// Read the axis' switch now. Answer `Switch`.
    ReadSwitch { axis: u8 },
    /// Move the axis `mm` away from its switch (hard limits are off for the
    /// whole cycle), wait until it stands, then read the switch. Answer
    /// `Switch`, or `Stopped`.
    PullOff { axis: u8, mm: f32, feed_mm_per_min: f32 },
    /// Move the axis up to `mm` toward its switch, the ISR watching it;
    /// where it trips is position 0. Answer `Seek`, or `Stopped`.
    Seek { axis: u8, mm: f32, feed_mm_per_min: f32 },
    /// The axis is homed: set its homed bit. Answer `Done`.
    Homed { axis: u8 },
    /// Every axis of the mask is homed.
    Done,
    /// A switch was not found, or did not let go: the homing alarm.
    Fail,
    /// An action was stopped on its way (alarm, abort): its error stands.
    Stop,
}

/// The runner's answer to an action.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// The action completed.
    Done,
    /// The switch reads closed (`true`) or open.
    Switch(bool),
    /// The seek ended: the switch tripped (`true`) or the move ended first.
    Seek(bool),
    /// The action was stopped on its way.
    Stopped,
}

/// Everything the cycle needs to know when it is asked for (the settings
/// as they are when it starts).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// Axes to home, bit i = axis i (X, Y, Z; other bits are ignored).
    pub mask: u8,
    /// Travel of X, Y, Z, mm.
    pub travel_mm: [f32; 3],
    /// `$27`, mm (at least [`MIN_PULLOFF_MM`] is used).
    pub pulloff_mm: f32,
    /// `$25`, mm/min.
    pub seek_feed_mm_per_min: f32,
    /// `$24`, mm/min.
    pub locate_feed_mm_per_min: f32,
}

/// The pull-off actually used for `$27 = mm` (also the distance a homed
/// axis' switch may stay closed above 0: `Machine::apply_watch`).
pub fn pulloff_mm(mm: f32) -> f32 {
    // Not `mm.max(MIN_PULLOFF_MM)`: f32::max links compiler-builtins'
    // fmaximum_numf (142 bytes; measured with nightly-2026-05-19 the image
    // grows by 98 bytes). The comparison gives the same for NaN (0.1).
    if mm >= MIN_PULLOFF_MM {
        mm
    } else {
        MIN_PULLOFF_MM
    }
}

/// A running homing cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cycle {
    req: Request,
    /// How many axes of the order Z, Y, X are behind (homed or not in the
    /// mask): the axis being homed is `nth_axis(axis_at)`.
    axis_at: u8,
    /// Index of the current row in [`TABLE`].
    at: u8,
    /// The axis' switch read closed in `ReadSwitch`.
    on_switch: bool,
    /// Set once the cycle ended: the action it ended with.
    end: Option<Action>,
}

impl Cycle {
    /// A cycle for `req` (nothing happens until [`Cycle::start`]).
    pub fn new(req: &Request) -> Cycle {
        let mut req = *req;
        req.pulloff_mm = pulloff_mm(req.pulloff_mm);
        Cycle { req, axis_at: 0, at: 0, on_switch: false, end: None }
    }

    /// The axis being homed and its state; `None` once the cycle ended.
    pub fn state(&self) -> Option<(u8, State)> {
        if self.end.is_some() {
            return None;
        }
        let axis = nth_axis(self.axis_at)?;
        row_at(self.at as usize).map(|r| (axis, r.state))
    }

    /// The first action.
    pub fn start(&mut self) -> Action {
        self.axis_at = 0;
        self.next_axis();
        self.action()
    }

    /// Feed the outcome of the last action; returns the next one.
    pub fn step(&mut self, ev: Event) -> Action {
        if let Some(end) = self.end {
            return end;
        }
        let act = row_at(self.at as usize).map(|r| r.act);
        match (act, ev) {
            (_, Event::Stopped) => return self.finish(Action::Stop),
            (Some(Do::ReadSwitch), Event::Switch(closed)) => self.on_switch = closed,
            // A pull-off must leave the switch open (one shorter than the
            // switch's hysteresis fails here, not later as a hard limit on
            // the first move: grbl's alarm 8); a seek must find it.
            (Some(Do::PullOff(_)), Event::Switch(true)) | (Some(Do::Seek(..)), Event::Seek(false)) => return self.finish(Action::Fail),
            _ => {}
        }
        self.at = self.next_row(self.at as usize + 1) as u8;
        if self.at as usize == TABLE.len() {
            self.axis_at += 1;
            self.next_axis();
        }
        self.action()
    }

    /// End the cycle with `a` (every later step returns it too).
    fn finish(&mut self, a: Action) -> Action {
        self.end = Some(a);
        a
    }

    /// From `axis_at` on, the first axis of the mask, at its first row.
    fn next_axis(&mut self) {
        while let Some(a) = nth_axis(self.axis_at) {
            if self.req.mask & (1 << a) != 0 {
                self.on_switch = false;
                self.at = self.next_row(0) as u8;
                return;
            }
            self.axis_at += 1;
        }
    }

    /// First row at or after `i` that applies.
    fn next_row(&self, mut i: usize) -> usize {
        while let Some(r) = row_at(i) {
            let applies = match r.when {
                When::Always => true,
                When::OnSwitch => self.on_switch,
            };
            if applies {
                break;
            }
            i += 1;
        }
        i
    }

    /// The action of the current row of the current axis.
    fn action(&mut self) -> Action {
        let Some(axis) = nth_axis(self.axis_at) else {
            return self.finish(Action::Done);
        };
        let Some(row) = row_at(self.at as usize) else {
            return self.finish(Action::Done);
        };
        let r = &self.req;
        let feed = |f: Feed| match f {
            Feed::Seek => r.seek_feed_mm_per_min,
            Feed::Locate => r.locate_feed_mm_per_min,
        };
        match row.act {
            Do::Unhome => Action::Unhome { axis },
            Do::ReadSwitch => Action::ReadSwitch { axis },
            Do::PullOff(f) => Action::PullOff { axis, mm: r.pulloff_mm, feed_mm_per_min: feed(f) },
            Do::Seek(reach, f) => {
                let mm = match reach {
                    Reach::Travel => r.travel_mm[axis as usize] * SEEK_MARGIN,
                    Reach::TwoPullOffs => r.pulloff_mm * 2.0,
                };
                Action::Seek { axis, mm, feed_mm_per_min: feed(f) }
            }
            Do::Homed => Action::Homed { axis },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(mask: u8) -> Request {
        Request { mask, travel_mm: [45.0, 40.0, 30.0], pulloff_mm: 1.0, seek_feed_mm_per_min: 1200.0, locate_feed_mm_per_min: 100.0 }
    }

    /// A runner that answers from `closed` (the switch when read, per axis
    /// and read count) and `trips` (each seek trips); the actions handed
    /// out, the states they came from, and how it ended.
    fn run(req: &Request, on_switch_at_start: u8, answer: impl Fn(&Action) -> Option<Event>) -> (Vec<(u8, State)>, Vec<Action>, Action) {
        let mut c = Cycle::new(req);
        let (mut states, mut actions) = (Vec::new(), Vec::new());
        let mut a = c.start();
        while !matches!(a, Action::Done | Action::Fail | Action::Stop) {
            states.push(c.state().unwrap());
            actions.push(a);
            let ev = answer(&a).unwrap_or(match a {
                Action::ReadSwitch { axis } => Event::Switch(on_switch_at_start & (1 << axis) != 0),
                Action::PullOff { .. } => Event::Switch(false),
                Action::Seek { .. } => Event::Seek(true),
                _ => Event::Done,
            });
            a = c.step(ev);
            assert!(actions.len() < 100, "runaway cycle");
        }
        assert_eq!(c.state(), None);
        assert_eq!(c.step(Event::Done), a, "an ended cycle keeps its end");
        (states, actions, a)
    }

    fn axis_of(a: &Action) -> Option<u8> {
        match *a {
            Action::Unhome { axis }
            | Action::ReadSwitch { axis }
            | Action::PullOff { axis, .. }
            | Action::Seek { axis, .. }
            | Action::Homed { axis } => Some(axis),
            _ => None,
        }
    }

    #[test]
    fn one_axis_off_its_switch_seeks_fast_backs_off_seeks_slowly_and_backs_off() {
        let (states, actions, end) = run(&request(0b100), 0, |_| None);
        assert_eq!(end, Action::Done);
        let z = |s| (2u8, s);
        assert_eq!(
            states,
            [
                z(State::Unhome),
                z(State::ReadSwitch),
                z(State::FastSeek),
                z(State::BackOff),
                z(State::SlowSeek),
                z(State::FinalPullOff),
                z(State::Homed)
            ]
        );
        assert_eq!(
            actions,
            [
                Action::Unhome { axis: 2 },
                Action::ReadSwitch { axis: 2 },
                Action::Seek { axis: 2, mm: 30.0 * 1.1, feed_mm_per_min: 1200.0 },
                Action::PullOff { axis: 2, mm: 1.0, feed_mm_per_min: 1200.0 },
                Action::Seek { axis: 2, mm: 2.0, feed_mm_per_min: 100.0 },
                Action::PullOff { axis: 2, mm: 1.0, feed_mm_per_min: 100.0 },
                Action::Homed { axis: 2 },
            ]
        );
    }

    #[test]
    fn an_axis_on_its_switch_leaves_it_first_at_the_locate_feed() {
        let (states, actions, end) = run(&request(0b001), 0b001, |_| None);
        assert_eq!(end, Action::Done);
        assert_eq!(states[2], (0, State::LeaveSwitch));
        assert_eq!(actions[2], Action::PullOff { axis: 0, mm: 1.0, feed_mm_per_min: 100.0 });
        assert_eq!(states.len(), 8);
    }

    #[test]
    fn the_axes_go_z_then_y_then_x_and_only_those_of_the_mask() {
        let order = |mask| {
            let (_, actions, end) = run(&request(mask), 0, |_| None);
            assert_eq!(end, Action::Done);
            let mut axes: Vec<u8> = actions.iter().filter_map(axis_of).collect();
            axes.dedup();
            axes
        };
        assert_eq!(order(0b111), [2, 1, 0]);
        assert_eq!(order(0b011), [1, 0]);
        assert_eq!(order(0b101), [2, 0]);
        // The carousel's bit (E) is not G28's.
        assert_eq!(order(0b1000), []);
        assert_eq!(order(0), []);
    }

    #[test]
    fn each_axis_seeks_its_own_travel() {
        let (_, actions, _) = run(&request(0b111), 0, |_| None);
        let fast: Vec<(u8, f32)> = actions
            .iter()
            .filter_map(|a| match *a {
                Action::Seek { axis, mm, feed_mm_per_min: 1200.0 } => Some((axis, mm)),
                _ => None,
            })
            .collect();
        assert_eq!(fast, [(2, 30.0 * 1.1), (1, 40.0 * 1.1), (0, 45.0 * 1.1)]);
    }

    #[test]
    fn a_seek_that_finds_no_switch_fails_and_nothing_after_it_runs() {
        for nth in 0..2 {
            let seeks = core::cell::Cell::new(0);
            let (_, actions, end) = run(&request(0b111), 0, |a| match a {
                Action::Seek { .. } => {
                    seeks.set(seeks.get() + 1);
                    Some(Event::Seek(seeks.get() != nth + 1))
                }
                _ => None,
            });
            assert_eq!(end, Action::Fail, "seek {nth}");
            assert!(matches!(actions.last(), Some(Action::Seek { axis: 2, .. })));
            assert!(!actions.iter().any(|a| matches!(a, Action::Homed { .. })));
        }
    }

    #[test]
    fn a_pull_off_that_leaves_the_switch_closed_fails() {
        // Starting on the switch and staying on it (a stuck switch).
        let (_, actions, end) = run(&request(0b010), 0b010, |a| matches!(a, Action::PullOff { .. }).then_some(Event::Switch(true)));
        assert_eq!(end, Action::Fail);
        assert_eq!(actions.len(), 3);
        // The last pull-off shorter than the switch's hysteresis.
        let pulls = core::cell::Cell::new(0);
        let (_, actions, end) = run(&request(0b010), 0, |a| match a {
            Action::PullOff { .. } => {
                pulls.set(pulls.get() + 1);
                Some(Event::Switch(pulls.get() == 2))
            }
            _ => None,
        });
        assert_eq!(end, Action::Fail);
        assert!(matches!(actions.last(), Some(Action::PullOff { feed_mm_per_min: 100.0, .. })));
    }

    #[test]
    fn a_stopped_action_ends_the_cycle_without_the_homing_alarm() {
        let (_, actions, end) = run(&request(0b111), 0, |a| matches!(a, Action::Seek { axis: 1, .. }).then_some(Event::Stopped));
        assert_eq!(end, Action::Stop);
        assert!(actions.contains(&Action::Homed { axis: 2 }));
        assert!(!actions.contains(&Action::Homed { axis: 1 }));
    }

    #[test]
    fn the_pull_off_is_at_least_a_tenth_of_a_millimetre() {
        assert_eq!(pulloff_mm(2.5), 2.5);
        assert_eq!(pulloff_mm(0.1), 0.1);
        assert_eq!(pulloff_mm(0.0), MIN_PULLOFF_MM);
        assert_eq!(pulloff_mm(-1.0), MIN_PULLOFF_MM);
        assert_eq!(pulloff_mm(f32::NAN), MIN_PULLOFF_MM);
        let mut r = request(0b100);
        r.pulloff_mm = 0.0;
        let (_, actions, _) = run(&r, 0, |_| None);
        assert!(actions.contains(&Action::Seek { axis: 2, mm: 0.2, feed_mm_per_min: 100.0 }));
    }

    #[test]
    fn every_row_is_reachable_and_in_order() {
        let (states, _, _) = run(&request(0b001), 0b001, |_| None);
        let want: Vec<State> = TABLE.iter().map(|r| r.state).collect();
        assert_eq!(states.iter().map(|s| s.1).collect::<Vec<_>>(), want);
    }
}
