#!/usr/bin/env python3
"""Drive bCNC 0.9.16's own sender headless on the simulated board.

bCNC's window (bmain.py) is a Tk subclass of its `Sender`; this driver
subclasses the same `Sender` without a window and does what the window's
buttons do: connect (open), Unlock ($X), a jog button ($J=G91 X10 F100000,
GRBL1.jog), a job run through Sender's own streaming thread with the feed
slider moved to 130 % and back (CNC.vars _OvFeed/_OvChanged, which the
thread turns into 0x91/0x90 through GRBL1.overrideSet), Feed hold and
Resume, Stop (stopRun: `!` then the purge), and Unlock after a hard limit.
tests/bcnc.rs owns the simulated board and reads the MARK lines this
prints (it records the position at each).

Usage: bcnc_drive.py PORT
"""
import os
import sys
import time

import builtins

import bCNC

# bCNC's main module installs gettext's `_` before its other modules load.
builtins._ = lambda s: s
HERE = os.path.dirname(bCNC.__file__)
sys.path[:0] = [HERE, os.path.join(HERE, "lib"), os.path.join(HERE, "controllers")]

import Utils  # noqa: E402

Utils.loadConfiguration()
from CNC import CNC, WAIT  # noqa: E402
from Sender import Sender  # noqa: E402


class Headless(Sender):
    """bCNC's sender with no window: the hooks its window provides."""

    def disable(self):
        pass

    def enable(self):
        pass


def out(s):
    print(s, flush=True)


def sleep(t):
    end = time.time() + t
    while time.time() < end:
        monitor()
        time.sleep(0.05)


def mark(name):
    out(f"MARK {name}")
    sleep(0.3)


def state():
    return str(CNC.vars.get("state", ""))


SENDER = None


def monitor():
    """What bmain's _monitorSerial does every 100 ms: take the sender's log
    and end a run once every line is acknowledged."""
    s = SENDER
    if s is None:
        return
    while s.log.qsize() > 0:
        kind, line = s.log.get_nowait()
        if kind == Sender.MSG_ERROR or "error" in str(line).lower() or "ALARM" in str(line):
            out(f"LOG bCNC: {str(line).strip()}")
    if s.running and s._gcount >= s._runLines:
        s.runEnded()


def wait_for(pred, what, timeout=20.0):
    t0 = time.time()
    while not pred():
        monitor()
        if time.time() - t0 > timeout:
            out(f"FAIL timeout: {what} (state {state()!r})")
            sys.exit(1)
        time.sleep(0.05)


def set_feed_slider(pct, timeout=5.0):
    """Move the feed slider to `pct` as a user does: bCNC's thread then
    sends one coarse or fine step a status poll (GRBL1.overrideSet, every
    0.125 s) from the override that the last report it parsed showed, and
    stops once that step should reach the target. Under load a report can
    come back after the next poll: bCNC then steps past the target and
    stops there (it looks again only while `_OvChanged` is set: 140 % for
    130 % in 1 run of 4 with two busy loops, and in 2 of 6 with the
    firmware before, so not the firmware's doing). A user who sees the
    reported override differ from the slider moves the slider again: so
    does this, once bCNC has stopped stepping and half a second of reports
    still disagree."""
    CNC.vars["_OvFeed"] = pct
    CNC.vars["_OvChanged"] = True
    t0 = time.time()
    settled = None
    while CNC.vars.get("OvFeed") != pct:
        monitor()
        if time.time() - t0 > timeout:
            out(f"FAIL timeout: OvFeed {pct} in the status (state {state()!r}, OvFeed {CNC.vars.get('OvFeed')})")
            sys.exit(1)
        if CNC.vars["_OvChanged"]:
            settled = None
        elif settled is None:
            settled = time.time()
        elif time.time() - settled > 0.5:
            out(f"LOG the slider again: the status says {CNC.vars.get('OvFeed')} %, the slider {pct} %")
            CNC.vars["_OvChanged"] = True
            settled = None
        time.sleep(0.05)


def run_job(s, lines):
    """What bmain.run does with a loaded file: queue the lines, then WAIT."""
    s.cleanAfter = True
    s.initRun()
    s._runLines = sys.maxsize
    s._gcount = 0
    CNC.vars["running"] = True
    CNC.vars["_OvChanged"] = True
    n = 1
    for line in lines:
        s.queue.put(line + "\n")
        n += 1
    s.queue.put((WAIT,))
    s._runLines = n


def main():
    global SENDER
    port = sys.argv[1]
    s = Headless()
    SENDER = s
    s.open(port, 250000)
    wait_for(lambda: state() not in ("", "Connected", "Not connected"), "a status report")
    out(f"LOG connected, state {state()}")
    s.unlock()
    wait_for(lambda: state() == "Idle", "Idle after Unlock")
    mark("ready")

    # A jog button: $J=G91 X10 F100000 (the feed is clamped to the max rate).
    s.mcontrol.jog("X10")
    sleep(0.5)
    wait_for(lambda: state() == "Idle", "Idle after the jog")
    mark("jog_end")

    # A job: 80 moves of 0.25 mm at F600 (20 mm, 2 s at 100 %); the feed
    # slider to 130 % after 0.6 s and back to 100 % after 1.2 s; a feed
    # hold of 1.5 s in the middle.
    mark("job_start")
    run_job(s, ["G21 G91"] + ["G1 X0.25 F600"] * 80 + ["G90"])
    sleep(0.6)
    set_feed_slider(130)
    mark("ov130")
    sleep(0.6)
    set_feed_slider(100)
    s.feedHold()
    wait_for(lambda: state().startswith("Hold"), "Hold after Feed hold", 5)
    sleep(0.5)
    mark("held")
    sleep(1.0)
    mark("held_end")
    s.resume()
    wait_for(lambda: not s.running, "the end of the job", 30)
    wait_for(lambda: state() == "Idle", "Idle at the end of the job")
    mark("job_end")

    # Stop: a job stopped after 0.8 s stays stopped.
    run_job(s, ["G21 G91"] + ["G1 X-0.25 F600"] * 60 + ["G90"])
    sleep(0.8)
    mark("stop")
    s.stopRun()
    s.runEnded()
    sleep(2.0)
    mark("stopped")
    sleep(1.0)
    mark("stopped_end")
    if state().lower().startswith("alarm"):
        s.unlock()
        sleep(0.5)

    # A hard limit: soft limits off, X into its switch; Unlock and a jog off it.
    s.sendGCode("$20=0")
    sleep(0.3)
    s.sendGCode("G91 G1 X-100 F600")
    wait_for(lambda: state().lower().startswith("alarm"), "the hard-limit alarm", 20)
    sleep(0.5)
    mark("alarm")
    s.unlock()
    wait_for(lambda: state() == "Idle", "Idle after Unlock from the hard limit", 5)
    mark("unlocked")
    s.sendGCode("$J=G91 X5 F600")
    sleep(0.5)
    wait_for(lambda: state() == "Idle", "Idle after the jog off the switch")
    mark("off_switch")
    s.sendGCode("G90")
    s.sendGCode("$20=1")
    sleep(0.5)
    s.close()
    out("DONE")
    os._exit(0)


if __name__ == "__main__":
    main()
