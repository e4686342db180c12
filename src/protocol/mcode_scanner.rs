//! The RX ISR's watch for `M112` (emergency stop) and `M108` (continue)
//! in the raw stream: [`MCodeScanner`], one byte of state, acting as the
//! bytes arrive rather than when the line is parsed.

/// What [`MCodeScanner::feed`] spotted on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Urgent {
    /// Nothing: the usual answer.
    Nothing,
    /// `M112`, emergency stop.
    Estop,
    /// `M108`, continue after M0/M1 (Marlin's emergency parser takes it too).
    Continue,
}

/// Watches the raw RX stream inside the ISR for the two M-codes that act as
/// the bytes arrive, not when the line is parsed (docs/SPEC.md §4): `M112` and
/// `M108`. One byte of state, O(1) per byte; the caller keeps the previous
/// byte, which only matters before an `M`.
///
/// Triggers on `M112` / `M108` (any case, no blanks inside) that does not
/// follow a letter, once the next byte shows it is not a longer number:
/// `M112\n`, `N7 M112*40`, `G0M112 ` trigger; `M1120`, `M11 2`, `AM112.GCO`
/// do not. It does not know about comments: `(M112)` triggers, which errs on
/// the safe side.
///
/// Most bytes neither start a match (no `M`) nor continue one, and
/// [`MCodeScanner::ignores`] says so with one compare: the RX ISR's fast
/// path checks that itself and skips the scanner for those bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MCodeScanner {
    /// How much of `M112` / `M108` matched: one of the `S_*` states.
    pub(super) state: u8,
}

/// [`MCodeScanner`] states: the prefix matched so far (0: none).
const S_M: u8 = 1;
const S_M1: u8 = 2;
const S_M11: u8 = 3;
const S_M112: u8 = 4;
const S_M10: u8 = 5;
pub(super) const S_M108: u8 = 6;

impl MCodeScanner {
    /// A scanner that has seen nothing.
    pub const fn new() -> Self {
        MCodeScanner { state: 0 }
    }

    /// True when nothing is matched.
    pub fn is_idle(&self) -> bool {
        self.state == 0
    }

    /// True when feeding `b` changes nothing and finds nothing: nothing is
    /// matched and `b` is no `M` or `m`.
    pub fn ignores(&self, b: u8) -> bool {
        self.state == 0 && b | 0x20 != b'm'
    }

    /// Feed one received byte `b`; `prev` is the byte fed before it (any
    /// non-letter at the start). Says which code `b` completes, if any.
    pub fn feed(&mut self, prev: u8, b: u8) -> Urgent {
        if self.ignores(b) {
            return Urgent::Nothing;
        }
        let mut found = Urgent::Nothing;
        let next = match (self.state, b) {
            (S_M112 | S_M108, b'0'..=b'9') => 0,
            (S_M112, _) => {
                found = Urgent::Estop;
                0
            }
            (S_M108, _) => {
                found = Urgent::Continue;
                0
            }
            (S_M, b'1') => S_M1,
            (S_M1, b'1') => S_M11,
            (S_M1, b'0') => S_M10,
            (S_M11, b'2') => S_M112,
            (S_M10, b'8') => S_M108,
            _ => 0,
        };
        // Only a non-digit ends a match, so an `M` may start the next one.
        self.state = if b | 0x20 == b'm' && !prev.is_ascii_alphabetic() { S_M } else { next };
        found
    }
}
