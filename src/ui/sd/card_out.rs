//! The card pulled while a job runs, scans or reads: the job ends, the
//! line named ([`SdJob::card_check`], [`SdJob::card_gone`]).

use super::{req, Card, Outcome, Phase, SdJob, Turn};
use crate::machine::Machine;
use crate::ui::text::Text;
use ufmt::{uWrite, uwriteln};

impl SdJob {
    /// The card is gone (`detected` false) while the job still runs: end
    /// it. Decelerate and drop every queued move, spindle kept (the tool is
    /// in the cut); once stopped, [`SdJob::poll`] has the tool retracted and
    /// the spindle stopped ([`Turn::RetractThenSpindleOff`]). Says at which
    /// line the job stopped. True when the job ended here. Called every
    /// main-loop turn, also while a job's line waits (a long arc, a full
    /// planner), so no queued move outlives the card.
    pub fn card_check(&mut self, detected: bool, m: &Machine, out: &mut impl uWrite) -> bool {
        if detected {
            return false;
        }
        if let Phase::Scanning(to) = self.phase {
            // Nothing moves during a scan: the job only ends.
            uwriteln!(out, "{}{}{}{}", Text::Echo, Text::MsgCardRemovedAt, to, Text::MsgNothingMoved).ok();
            self.not_resumed(to, Text::WhyCardOut);
            return true;
        }
        if !matches!(self.phase, Phase::Running | Phase::Paused | Phase::Draining(_))
            || matches!(self.phase, Phase::Draining(Outcome::NotResumed(_)))
        {
            return false;
        }
        let stopped = self.cut_line(m);
        self.reached = stopped;
        self.request(req::ABORT | req::KEEP_SPINDLE);
        self.phase = Phase::Aborting(Outcome::CardRemoved(stopped));
        uwriteln!(out, "{}{}{}", Text::Echo, Text::MsgCardRemovedAt, stopped).ok();
        true
    }

    /// A read failed with the card gone (pulled during the read): the
    /// card's removal, as [`SdJob::card_check`] reports it, not a read error.
    pub(super) fn card_gone(&mut self, card: &mut impl Card, m: &Machine, out: &mut impl uWrite) -> Turn {
        if self.card_check(false, m, out) {
            card.unmount();
        }
        Turn::Idle
    }
}
