#!/usr/bin/env python3
"""Drive the real OctoPrint server against the simulated board, as a user does.

Run by tests/octoprint.rs with the Python of target/octoprint-venv
(tools/setup-hosts installs OctoPrint there). The Rust test owns the virtual machine and the pty;
this script owns OctoPrint:

1. writes a fresh basedir: config.yaml with only what a user sets (the first-run
   wizard's choices, the connection dialog's port and baud, and the printer
   profile's tool count that docs/hosts.md "OctoPrint" tells a user to set), and one
   admin user with an API key (what `octoprint user add` plus "Generate API key"
   in the user settings make);
2. starts `octoprint serve` on 127.0.0.1 and talks to it only through its REST
   API and its push socket (the terminal tab's `Send:`/`Recv:` lines);
3. connects, uploads and runs the jobs named on the command line: the first to
   its end, the second paused and resumed, the third cancelled, then sends
   `M114` from the terminal API and waits for the answer;
4. scans octoprint.log and the terminal for errors and M112.

At each point where the board must be checked, it prints `CHECK <name>` and waits
for one line on stdin (the test answers after it has read the board's state).
Every other line it prints starts with `# ` (log) or `FAIL ` (a failed check).
The last line is `RESULT ok` or `RESULT failed <n>`.
"""

import argparse
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time

import requests
import websocket
import yaml

API_KEY = "MILLFWTEST0123456789ABCDEFGHIJKL"
USER = "mill"

failures = []


def log(msg):
    print("# " + msg, flush=True)


def fail(msg):
    failures.append(msg)
    print("FAIL " + msg, flush=True)


def checkpoint(name):
    print("CHECK " + name, flush=True)
    reply = sys.stdin.readline()
    if not reply:
        sys.exit("the test closed stdin")
    reply = reply.strip()
    if reply != "OK":
        fail(f"check {name}: {reply}")


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


# --------------------------------------------------------------- the basedir


def write_basedir(base, port_path, tools, extra):
    os.makedirs(os.path.join(base, "printerProfiles"), exist_ok=True)
    config = {
        # The first-run wizard's answers. The connectivity check is on but
        # points at a closed local port, so OctoPrint knows it is offline and
        # does not try the internet (update checks, plugin repository, news):
        # CI has no network, and those fetches would log errors of their own.
        "server": {
            "firstRun": False,
            "onlineCheck": {"enabled": True, "host": "127.0.0.1", "port": 9, "name": "localhost"},
            "pluginBlacklist": {"enabled": False},
        },
        "plugins": {"tracking": {"enabled": False}},
        # The connection dialog: port and baud ("Save connection settings").
        # A pty is not a /dev/ttyUSB*/ttyACM* name, so it is listed as an
        # additional port (Settings > Serial Connection > Additional serial ports).
        "serial": {
            "port": port_path,
            "baudrate": 250000,
            "additionalPorts": [port_path],
        },
        # The printer profile docs/hosts.md "OctoPrint" tells a user to set.
        "printerProfiles": {"default": "mill"},
    }
    for key, value in extra.items():  # --extra-config: for investigations only
        config.setdefault(key, {}).update(value)
    with open(os.path.join(base, "config.yaml"), "w") as f:
        yaml.safe_dump(config, f)
    # Settings > Printer Profiles > Extruder: 13 extruders (T0 = empty
    # spindle, T1-T12 the pockets), "shared nozzle" (one spindle: one
    # temperature and one `M104 T0 S0` in the cancel script).
    # Everything else is OctoPrint's default profile, as the dialog saves it.

    from octoprint.printer.profile import PrinterProfileManager

    profile = json.loads(json.dumps(PrinterProfileManager.default))
    profile.update({"id": "mill", "name": "MillFW mill", "model": "RAMPS 1.4 mill, 12-pocket changer"})
    profile["extruder"]["count"] = tools
    profile["extruder"]["sharedNozzle"] = True
    profile["extruder"]["offsets"] = [[0.0, 0.0]] * tools
    with open(os.path.join(base, "printerProfiles", "mill.profile"), "w") as f:
        yaml.safe_dump(profile, f)
    from octoprint.access.users import FilebasedUserManager

    users = {
        USER: {
            "active": True,
            "apikey": API_KEY,
            "password": FilebasedUserManager.create_password_hash("mill-test"),
            "groups": ["admins", "users"],
            "permissions": [],
            "settings": {},
        }
    }
    with open(os.path.join(base, "users.yaml"), "w") as f:
        yaml.safe_dump(users, f)


# --------------------------------------------------------------- the server


class OctoPrint:
    def __init__(self, base, http_port):
        self.base = base
        self.url = f"http://127.0.0.1:{http_port}"
        self.http = requests.Session()
        self.http.headers["X-Api-Key"] = API_KEY
        exe = os.path.join(os.path.dirname(sys.executable), "octoprint")
        self.out = open(os.path.join(base, "serve.out"), "w")
        self.proc = subprocess.Popen(
            [exe, "serve", "--iknowwhatimdoing", "--host", "127.0.0.1", "--port", str(http_port), "--basedir", base],
            stdout=self.out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
        )
        self.terminal = []  # the terminal tab: "Send: ..." / "Recv: ..."
        self.events = []  # (type, payload)
        self.state = {}
        self.lock = threading.Lock()
        self.disconnect_at = None  # index of the first event after our own disconnect
        self.terminal_at = None  # terminal lines before the disconnect mid-job (step 4)
        self.oplog_at = None  # octoprint.log bytes before it

    def get(self, path):
        r = self.http.get(self.url + path, timeout=10)
        r.raise_for_status()
        return r.json()

    def post(self, path, body=None, **kw):
        r = self.http.post(self.url + path, json=body, timeout=30, **kw)
        if r.status_code >= 400:
            raise RuntimeError(f"POST {path} {body}: HTTP {r.status_code} {r.text[:300]}")
        return r.json() if r.text else None

    def wait_up(self, timeout):
        end = time.time() + timeout
        while time.time() < end:
            if self.proc.poll() is not None:
                raise RuntimeError(f"octoprint serve exited with {self.proc.returncode}")
            try:
                v = self.get("/api/version")
                return v
            except Exception:
                time.sleep(0.5)
        raise RuntimeError("OctoPrint did not answer within %d s" % timeout)

    def open_socket(self):
        login = self.post("/api/login", {"passive": True})
        ws_url = self.url.replace("http://", "ws://") + "/sockjs/websocket"
        self.ws = websocket.create_connection(ws_url, timeout=10)
        self.ws.send(json.dumps({"auth": f"{login['name']}:{login['session']}"}))
        self.ws_thread = threading.Thread(target=self._read_socket, daemon=True)
        self.ws_thread.start()

    def _read_socket(self):
        while True:
            try:
                msg = self.ws.recv()
            except websocket.WebSocketTimeoutException:
                continue
            except Exception:
                return
            if not msg:
                continue
            try:
                data = json.loads(msg)
            except ValueError:
                continue
            with self.lock:
                for kind in ("current", "history"):
                    if kind in data:
                        self.terminal.extend(data[kind].get("logs", []))
                        self.state = data[kind].get("state", self.state)
                if "event" in data:
                    self.events.append((data["event"]["type"], data["event"].get("payload")))

    def event_count(self):
        with self.lock:
            return len(self.events)

    def wait_event(self, names, since, timeout, bad=()):
        """The first event named in `names` after index `since`; a `bad` one fails."""
        end = time.time() + timeout
        while time.time() < end:
            with self.lock:
                for kind, payload in self.events[since:]:
                    if kind in bad and bad_event(kind, payload):
                        return kind, payload
                    if kind in names:
                        return kind, payload
            if self.proc.poll() is not None:
                raise RuntimeError("octoprint serve exited")
            time.sleep(0.2)
        return None, None

    def connection_state(self):
        return self.get("/api/connection")["current"]["state"]

    def wait_state(self, states, timeout):
        end = time.time() + timeout
        st = None
        while time.time() < end:
            st = self.connection_state()
            if st in states:
                return st
            time.sleep(0.3)
        return st

    def terminal_len(self):
        with self.lock:
            return len(self.terminal)

    def terminal_since(self, i):
        with self.lock:
            return list(self.terminal[i:])

    def stop(self):
        try:
            self.ws.close()
        except Exception:
            pass
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.out.close()


# --------------------------------------------------------------- the jobs

# Events that end a job or the connection badly. A cancel fires PrintCancelled
# and then PrintFailed with reason "cancelled" (OctoPrint 1.11): that one is
# expected, see bad_event().
BAD_EVENTS = ("Error", "Disconnected", "PrintFailed", "EStop")


def bad_event(kind, payload):
    if kind == "PrintFailed" and (payload or {}).get("reason") == "cancelled":
        return False
    return kind in BAD_EVENTS


def upload(op, path):
    name = os.path.basename(path)
    with open(path, "rb") as f:
        op.post("/api/files/local", files={"file": (name, f)}, data={"select": "false", "print": "false"})
    return name


def start_job(op, name):
    since = op.event_count()
    op.post(f"/api/files/local/{name}", {"command": "select", "print": True})
    kind, payload = op.wait_event(("PrintStarted",), since, 30, BAD_EVENTS)
    if kind != "PrintStarted":
        fail(f"{name}: no PrintStarted after select+print (got {kind} {payload})")
        return None
    log(f"{name}: printing")
    return since


def wait_job_end(op, name, since, timeout):
    t0 = time.time()
    kind, payload = op.wait_event(("PrintDone", "PrintCancelled"), since, timeout, BAD_EVENTS)
    if kind != "PrintDone":
        fail(f"{name}: expected PrintDone, got {kind} {payload} after {time.time() - t0:.0f} s "
             f"(connection state {op.connection_state()})")
        return False
    log(f"{name}: done after {payload.get('time', 0):.1f} s (OctoPrint's print time)")
    return True


def wait_filepos(op, at_least, timeout):
    end = time.time() + timeout
    while time.time() < end:
        job = op.get("/api/job")
        pos = (job.get("progress") or {}).get("filepos") or 0
        if pos >= at_least:
            return pos
        if job.get("state") not in ("Printing", "Starting", "Starting print"):
            return None
        time.sleep(0.2)
    return None


def run(args):
    base = args.basedir
    write_basedir(base, args.port, args.tools, yaml.safe_load(args.extra_config) if args.extra_config else {})
    http_port = free_port()
    op = OctoPrint(base, http_port)
    try:
        t0 = time.time()
        v = op.wait_up(120)
        log(f"{v['text']} up on 127.0.0.1:{http_port} after {time.time() - t0:.1f} s")
        op.open_socket()

        # Connect as the connection dialog does (port, baud, profile).
        since = op.event_count()
        op.post("/api/connection", {"command": "connect", "port": args.port, "baudrate": 250000,
                                    "printerProfile": "mill"})
        st = op.wait_state(("Operational", "Error", "Offline", "Offline after error"), 60)
        kind, _ = op.wait_event(("Connected",), since, 5)
        log(f"connect: state {st}")
        if st != "Operational":
            fail(f"connect: state {st!r}, not Operational")
            return
        # Let the handshake finish (M115, M21, the first temperature polls)
        # and see that the connection stays up.
        time.sleep(args.settle)
        st = op.connection_state()
        if st != "Operational":
            fail(f"connect: state {st!r} {args.settle} s after connecting")
            return
        printer = op.get("/api/printer")
        log(f"connected: {printer['state']['text']}")
        checkpoint("connected")

        # 1. A job to its end.
        name = upload(op, args.run)
        since = start_job(op, name)
        if since is None or not wait_job_end(op, name, since, args.job_timeout):
            return
        time.sleep(1)
        checkpoint("run-done")

        # 2. Pause and resume.
        name = upload(op, args.pause)
        since = start_job(op, name)
        if since is None:
            return
        size = os.path.getsize(args.pause)
        pos = wait_filepos(op, size // 2, args.job_timeout)
        if pos is None:
            fail(f"{name}: never reached half the file ({op.get('/api/job')})")
            return
        ev = op.event_count()
        op.post("/api/job", {"command": "pause", "action": "pause"})
        kind, payload = op.wait_event(("PrintPaused",), ev, 30, BAD_EVENTS)
        if kind != "PrintPaused":
            fail(f"{name}: pause: got {kind} {payload}")
            return
        st = op.wait_state(("Paused",), 30)
        log(f"{name}: paused at file byte {pos} of {size}, state {st}")
        if st != "Paused":
            fail(f"{name}: state {st!r} after pause")
        # The queued moves drain; then nothing moves.
        time.sleep(args.drain)
        checkpoint("paused-1")
        time.sleep(2)
        checkpoint("paused-2")
        ev = op.event_count()
        op.post("/api/job", {"command": "pause", "action": "resume"})
        kind, payload = op.wait_event(("PrintResumed",), ev, 30, BAD_EVENTS)
        if kind != "PrintResumed":
            fail(f"{name}: resume: got {kind} {payload}")
            return
        if not wait_job_end(op, name, since, args.job_timeout):
            return
        time.sleep(1)
        checkpoint("pause-done")

        # 3. Cancel.
        name = upload(op, args.cancel)
        since = start_job(op, name)
        if since is None:
            return
        size = os.path.getsize(args.cancel)
        pos = wait_filepos(op, size // 3, args.job_timeout)
        if pos is None:
            fail(f"{name}: never reached a third of the file ({op.get('/api/job')})")
            return
        time.sleep(1)
        checkpoint("cancel-before")
        ev = op.event_count()
        op.post("/api/job", {"command": "cancel"})
        kind, payload = op.wait_event(("PrintCancelled",), ev, 30, BAD_EVENTS)
        if kind != "PrintCancelled":
            fail(f"{name}: cancel: got {kind} {payload}")
            return
        st = op.wait_state(("Operational",), 60)
        log(f"{name}: cancelled at file byte {pos} of {size}, state {st}")
        if st != "Operational":
            fail(f"{name}: state {st!r} after cancel")
        time.sleep(args.drain)
        # The serial line still answers: M114 from the terminal.
        i = op.terminal_len()
        op.post("/api/printer/command", {"commands": ["M114"]})
        end = time.time() + 15
        answer = None
        while time.time() < end and answer is None:
            for line in op.terminal_since(i):
                if line.startswith("Recv: X:"):
                    answer = line
            time.sleep(0.2)
        if answer is None:
            fail(f"M114 after cancel: no position in the terminal: {op.terminal_since(i)}")
        else:
            log(f"M114 after cancel: {answer}")
        checkpoint("cancelled")
        st = op.connection_state()
        if st != "Operational":
            fail(f"after cancel and M114: state {st!r}")

        # 4. Disconnect and connect again in the middle of a job (a second
        # OctoPrint, a restart): opening the port resets the board
        # (auto-reset). The job is gone, the position too, and a move is
        # refused until the machine is homed. From here OctoPrint's own
        # complaints about the lost print are expected (scan stops here).
        name = upload(op, args.reconnect)
        since = start_job(op, name)
        if since is None:
            return
        if wait_filepos(op, 20, args.job_timeout) is None:
            fail(f"{name}: never started sending ({op.get('/api/job')})")
            return
        time.sleep(2)
        checkpoint("reconnect-before")
        op.disconnect_at = op.event_count()
        op.terminal_at = op.terminal_len()
        oplog = os.path.join(base, "logs", "octoprint.log")
        op.oplog_at = os.path.getsize(oplog) if os.path.exists(oplog) else None
        op.post("/api/connection", {"command": "disconnect"})
        op.wait_state(("Offline", "Closed"), 20)
        op.post("/api/connection", {"command": "connect", "port": args.port, "baudrate": 250000,
                                    "printerProfile": "mill"})
        st = op.wait_state(("Operational", "Error", "Offline", "Offline after error"), 60)
        log(f"reconnect: state {st}")
        if st != "Operational":
            fail(f"reconnect: state {st!r}, not Operational")
            return
        time.sleep(args.settle)
        checkpoint("reconnected")
        i = op.terminal_len()
        op.post("/api/printer/command", {"commands": ["M114", "G91", "G1 X1 F600", "G90"]})
        end = time.time() + 15
        seen = []
        while time.time() < end and not (any(l.startswith("Recv: X:0.000") for l in seen)
                                         and any(l.startswith("Recv: Error:not homed") for l in seen)):
            seen = op.terminal_since(i)
            time.sleep(0.2)
        if not any(l.startswith("Recv: X:0.000") for l in seen):
            fail(f"reconnected: M114 does not say X:0.000: {seen}")
        if not any(l.startswith("Recv: Error:not homed") for l in seen):
            fail(f"reconnected: the move was not refused: {seen}")
        else:
            log("reconnected: position 0, a move refused until homed")
        op.post("/api/connection", {"command": "disconnect"})
        op.wait_state(("Offline", "Closed"), 20)
    finally:
        op.stop()
        scan(op, base, args.expect_tools.split(",") if args.expect_tools else None)


def scan(op, base, expect_tools):
    with open(os.path.join(base, "terminal.log"), "w") as f:
        f.write("\n".join(op.terminal) + "\n")
    with open(os.path.join(base, "events.log"), "w") as f:
        for kind, payload in op.events:
            f.write(f"{kind} {json.dumps(payload)}\n")
    oplog = os.path.join(base, "logs", "octoprint.log")
    raw = open(oplog, "rb").read() if os.path.exists(oplog) else b""
    # Up to the deliberate disconnect mid-job (step 4).
    text = raw[: op.oplog_at].decode(errors="replace")
    for line in text.splitlines():
        if re.search(r" - (ERROR|CRITICAL) - ", line) or " octoprint.util.comm - WARNING - " in line:
            fail("octoprint.log: " + line)
        elif "M112" in line:
            fail("octoprint.log mentions M112: " + line)
    for line in op.terminal[: op.terminal_at]:
        body = line.split(":", 1)[1].strip() if ":" in line else line
        if line.startswith("Send:") and re.search(r"\bM112\b", body):
            fail("terminal: " + line)
        if line.startswith("Recv:") and re.match(r"(?i)(error|!!|alarm)", body):
            fail("terminal: " + line)
        if line.startswith("Warn:"):  # e.g. "Warn: Not queuing T5, that tool doesn't exist..."
            fail("terminal: " + line)
        if re.search(r"(?i)communication timeout|No response from printer", line):
            fail("terminal: " + line)
    # OctoPrint's own view of the tool changes (it fires ToolChange when it has
    # sent a T: a T it drops for the profile never shows here).
    tools = [str((p or {}).get("new")) for kind, p in op.events if kind == "ToolChange"]
    if expect_tools is not None and tools != expect_tools:
        fail(f"OctoPrint's ToolChange events {tools}, expected {expect_tools}")
    events = op.events if op.disconnect_at is None else op.events[: op.disconnect_at]
    for kind, payload in events:
        if bad_event(kind, payload):
            fail(f"event {kind} {json.dumps(payload)[:2000]}")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--port", required=True, help="the pty the board listens on")
    p.add_argument("--basedir", required=True)
    p.add_argument("--run", required=True, help="job run to its end")
    p.add_argument("--pause", required=True, help="job paused and resumed")
    p.add_argument("--cancel", required=True, help="job cancelled")
    p.add_argument("--reconnect", required=True, help="job during which OctoPrint disconnects and connects again")
    p.add_argument("--tools", type=int, default=13, help="printer profile extruder count")
    p.add_argument("--settle", type=float, default=5)
    p.add_argument("--drain", type=float, default=4, help="seconds for queued moves to drain")
    p.add_argument("--job-timeout", type=float, default=300)
    p.add_argument("--expect-tools", help="the tools OctoPrint must change to, in order (e.g. 1,2,0)")
    p.add_argument("--extra-config", help="YAML merged into config.yaml, to investigate by hand (the test never uses it)")
    args = p.parse_args()
    try:
        run(args)
    except Exception as e:  # report, never hang the test
        fail(f"driver: {type(e).__name__}: {e}")
    print(f"RESULT {'ok' if not failures else 'failed %d' % len(failures)}", flush=True)
    sys.exit(0 if not failures else 1)


if __name__ == "__main__":
    main()
