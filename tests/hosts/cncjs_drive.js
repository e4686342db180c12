#!/usr/bin/env node
// Drives a running cncjs server over its Socket.IO API, as its web page does,
// for tests/cncjs.rs. The test harness owns the simulated board: this driver
// asks it, over stdin/stdout, to mark instants and to wait for the recorded
// steps (see `harness` below), and does everything else through cncjs:
//
//   open the port (controllerType, 250000 baud) -> unlock -> job A to the end
//   -> job B with Pause/Resume (and in Grbl mode Feed hold/Cycle start and
//      the feed override buttons: +10 % three times, then 100 %)
//   -> job C stopped with the Stop button (gcode:stop {force: true}), then
//      Cycle start and a raw `~`, then a question to the machine -> job D
//   -> (Grbl) job F with a refused line: cncjs pauses on the error; Stop
//   -> (Grbl) a hard limit, Unlock and a jog off the switch
//   -> job E, during which the port is closed and opened again (auto-reset).
//
// Usage: node cncjs_drive.js URL SECRET PORT Grbl|Marlin JOBDIR
// Needs socket.io-client 2.2 (the major version of cncjs 1.11's server) on
// NODE_PATH. Writes `MARK name`, `WAIT_MOVED name steps timeout_s`,
// `WAIT_STILL still_s timeout_s`, `LOG text`, `READ text` (a line cncjs
// relayed from the machine), `WROTE text` (what cncjs wrote to it),
// `CHECK_FAIL reason` (a failed check after which the run goes on) and at the
// end `DONE` or `FAIL reason` on stdout; reads one reply line per request.
'use strict';

const crypto = require('crypto');
const fs = require('fs');
const path = require('path');
const readline = require('readline');
const io = require('socket.io-client');

const [url, secret, port, controllerType, jobDir] = process.argv.slice(2);
if (!jobDir || !['Grbl', 'Marlin'].includes(controllerType)) {
  console.error('usage: cncjs_drive.js URL SECRET PORT Grbl|Marlin JOBDIR');
  process.exit(2);
}
const grbl = controllerType === 'Grbl';
const t0 = Date.now();
const out = (s) => process.stdout.write(s.replace(/\r?\n/g, '\\n') + '\n');
const log = (s) => out(`LOG [${((Date.now() - t0) / 1000).toFixed(3)}] ${s}`);
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// --- the harness: one request, one reply line -------------------------------
const replies = [];
let replyWaiter = null;
readline.createInterface({ input: process.stdin }).on('line', (l) => {
  if (replyWaiter) {
    const w = replyWaiter;
    replyWaiter = null;
    w(l);
  } else {
    replies.push(l);
  }
});
const ask = (req) => new Promise((resolve) => {
  out(req);
  if (replies.length) resolve(replies.shift());
  else replyWaiter = resolve;
});
const mark = (name) => ask(`MARK ${name}`);
async function waitMoved(name, steps, timeoutS) {
  const r = await ask(`WAIT_MOVED ${name} ${steps} ${timeoutS}`);
  if (!r.startsWith('MOVED')) throw new Error(`no ${steps} steps after mark ${name}: ${r}`);
}
async function waitStill(stillS, timeoutS) {
  const r = await ask(`WAIT_STILL ${stillS} ${timeoutS}`);
  if (!r.startsWith('STILL')) throw new Error(`the machine did not stop within ${timeoutS} s: ${r}`);
  return r;
}

// --- the JWT the web page gets from /api/signin (HS256, cncjs's secret) -----
function token() {
  const b64 = (o) => Buffer.from(JSON.stringify(o)).toString('base64url');
  const now = Math.floor(Date.now() / 1000);
  const body = `${b64({ alg: 'HS256', typ: 'JWT' })}.${b64({ id: '', name: '', iat: now, exp: now + 3600 })}`;
  return `${body}.${crypto.createHmac('sha256', secret).update(body).digest('base64url')}`;
}

// --- cncjs events ----------------------------------------------------------
const socket = io.connect(url, { query: `token=${token()}`, transports: ['websocket'], reconnection: false });
let workflow = 'idle';
let activeState = '';
let ovFeed = 0;
const reads = [];
const waiters = [];
function notify() {
  for (let i = waiters.length - 1; i >= 0; i--) {
    if (waiters[i].test()) {
      waiters[i].resolve();
      waiters.splice(i, 1);
    }
  }
}
function until(test, timeoutMs, what) {
  return new Promise((resolve, reject) => {
    if (test()) return resolve();
    const w = { test, resolve };
    waiters.push(w);
    setTimeout(() => {
      const i = waiters.indexOf(w);
      if (i >= 0) {
        waiters.splice(i, 1);
        reject(new Error(`timeout after ${timeoutMs} ms: ${what}`));
      }
    }, timeoutMs);
  });
}
socket.on('connect', () => notify());
socket.on('connect_error', (e) => fail(`socket connect_error: ${e}`));
socket.on('error', (e) => fail(`socket error: ${JSON.stringify(e)}`));
socket.on('serialport:read', (line) => {
  out(`READ ${line}`);
  reads.push(String(line));
  notify();
});
socket.on('serialport:write', (data, ctx) => {
  out(`WROTE ${JSON.stringify(data)} ${ctx && ctx.source ? ctx.source : ''}`);
});
socket.on('serialport:error', (e) => fail(`serialport:error ${JSON.stringify(e)}`));
socket.on('workflow:state', (s) => {
  if (s !== workflow) log(`workflow ${workflow} -> ${s}`);
  workflow = s;
  notify();
});
socket.on('controller:state', (type, state) => {
  const s = (state && state.status && state.status.activeState) || '';
  const ov = state && state.status && state.status.ov;
  if (ov && ov.length && ov[0] !== ovFeed) {
    log(`ov ${JSON.stringify(ov)}`);
    ovFeed = ov[0];
  }
  if (s !== activeState) log(`activeState ${activeState || '-'} -> ${s || '-'}`);
  activeState = s;
  notify();
});
socket.on('sender:status', (s) => {
  if (s && s.hold) log(`sender hold ${JSON.stringify(s.holdReason)} sent=${s.sent} received=${s.received}`);
});

const command = (cmd, ...args) => {
  log(`command ${cmd} ${args.map((a) => (typeof a === 'string' && a.length > 40 ? `<${a.length} chars>` : JSON.stringify(a))).join(' ')}`);
  socket.emit('command', port, cmd, ...args);
};
const writeln = (data) => {
  log(`writeln ${JSON.stringify(data)}`);
  socket.emit('writeln', port, data);
};
const write = (data) => {
  log(`write ${JSON.stringify(data)}`);
  socket.emit('write', port, data);
};
const readsSince = (n) => reads.slice(n);

async function load(name) {
  const gcode = fs.readFileSync(path.join(jobDir, name), 'utf8');
  await new Promise((resolve, reject) => {
    socket.emit('command', port, 'gcode:load', name, gcode, {}, (err, state) => {
      if (err) reject(new Error(`gcode:load ${name}: ${err.message || err}`));
      else resolve(state);
    });
  });
  log(`loaded ${name}`);
}

// Start a loaded job and wait until cncjs itself ends the workflow (its
// sender is done and the machine is idle).
async function runToEnd(name, timeoutMs, during) {
  command('gcode:start');
  await until(() => workflow === 'running', 5000, `${name}: workflow running`);
  if (during) await during();
  await until(() => workflow === 'idle', timeoutMs, `${name}: workflow back to idle (the end of the job)`);
}

// Hold the machine with `hold`, check it is still, release with `release`.
async function holdAndRelease(label, hold, release) {
  await hold();
  const still = await waitStill(0.3, 8);
  log(`${label}: ${still}`);
  await mark(`${label}_held`);
  await sleep(1500);
  await mark(`${label}_held_end`);
  await release();
}

async function main() {
  await until(() => socket.connected, 10000, 'socket connected');
  log(`connected to ${url}`);
  await new Promise((resolve, reject) => {
    socket.emit('open', port, { controllerType, baudrate: 250000 }, (err) => (err ? reject(new Error(`open: ${err}`)) : resolve()));
  });
  log(`opened ${port} as ${controllerType}`);
  // Ready: grbl answers the controller's `?` with a status line; Marlin
  // answers its M115 with the firmware line.
  if (grbl) await until(() => activeState !== '', 15000, 'a grbl status report');
  else await until(() => reads.some((l) => l.includes('FIRMWARE_NAME')), 15000, 'the M115 firmware line');
  await mark('ready');

  // Unlock (the firmware refuses motion until homed or unlocked), as a user
  // does: grbl's Unlock button is `$X`; in Marlin mode, M999 in the console.
  let n = reads.length;
  if (grbl) command('unlock');
  else writeln('M999');
  await until(() => readsSince(n).some((l) => l.startsWith('ok')), 5000, 'ok to the unlock');

  // A: a job to the end.
  await load('a.nc');
  await mark('a_start');
  await runToEnd('job A', 60000);
  await waitStill(0.3, 10);
  await mark('a_end');

  // B: pause and resume (the workflow buttons), and in grbl mode also the
  // Feed hold / Cycle start buttons.
  await load('b.nc');
  await mark('b_start');
  await runToEnd('job B', 90000, async () => {
    await waitMoved('b_start', 150, 20);
    await holdAndRelease('b_pause', async () => command('gcode:pause'), async () => command('gcode:resume'));
    if (grbl) {
      await mark('b_resumed');
      await waitMoved('b_resumed', 150, 20);
      await holdAndRelease('b_feedhold', async () => command('feedhold'), async () => command('cyclestart'));
      // The feed override buttons: +10 % three times, then back to 100 %
      // (cncjs writes 0x91 and 0x90; the job must still end exactly).
      for (let i = 0; i < 3; i++) {
        command('feedOverride', 10);
        await sleep(250);
      }
      await until(() => ovFeed === 130, 5000, 'Ov: 130 after three +10 % clicks');
      await mark('b_ov130');
      await sleep(500);
      command('feedOverride', 0);
      await until(() => ovFeed === 100, 5000, 'Ov: 100 after the reset click');
    }
  });
  await waitStill(0.3, 10);
  await mark('b_end');

  // C: Stop during the job, then try to restart the old motion.
  await load('c.nc');
  await mark('c_start');
  command('gcode:start');
  await until(() => workflow === 'running', 5000, 'job C: workflow running');
  await waitMoved('c_start', 150, 20);
  // A user clicks Stop on a page that shows the machine running (cncjs's
  // grbl Stop only sends `!` when its last status report said Run), a
  // reaction time after the page showed it. Not at once: cncjs copies the
  // runner's state into the one its Stop reads on its 250 ms status tick,
  // the tick that also showed the page Run, and its Stop sends 0x18 only
  // if that state says Hold 500 ms after the click, so a click on the
  // tick itself raced cncjs's own timers (the tick two later against the
  // 500 ms): with the machine loaded, cncjs sometimes read Run and left
  // the old job queued in the hold (3 of 12 runs with three busy loops).
  if (grbl) await until(() => activeState === 'Run', 5000, 'job C: status Run');
  await sleep(150);
  await mark('c_stop');
  command('gcode:stop', { force: true });
  await until(() => workflow === 'idle', 5000, 'job C: workflow idle after Stop');
  // cncjs's grbl Stop sends `!`, then 0x18 500 ms later if the machine
  // reports Hold: let it finish before judging.
  await sleep(1000);
  const still = await waitStill(0.5, 15);
  log(`after Stop: ${still}`);
  await mark('c_still');
  command('cyclestart');
  await sleep(300);
  write('~');
  await sleep(2000);
  // The machine still answers.
  // The machine still answers (a failed answer is reported, and the job
  // after it still runs, so that every check gives its verdict).
  n = reads.length;
  try {
    if (grbl) {
      writeln('$G');
      await until(() => readsSince(n).some((l) => l.startsWith('[GC:')), 5000, 'the $G parser state line after Stop');
    } else {
      writeln('M114');
      await until(() => readsSince(n).some((l) => /X:-?[0-9.]+ Y:-?[0-9.]+/.test(l)), 5000, 'the M114 position line after Stop');
    }
  } catch (e) {
    out(`CHECK_FAIL ${e.message}; the machine answered ${JSON.stringify(readsSince(n))}`);
  }
  await mark('c_end');

  // D: a new job after the Stop runs exactly (relative moves: anything left
  // of job C would shift its end). Unlock first if the Stop left an alarm.
  if (grbl && activeState === 'Alarm') {
    n = reads.length;
    command('unlock');
    await until(() => readsSince(n).some((l) => l.startsWith('ok')), 5000, 'ok to $X');
  }
  await load('d.nc');
  await mark('d_start');
  await runToEnd('job D', 60000);
  await waitStill(0.3, 10);
  await mark('d_end');

  if (grbl) {
    // F: a job with a line the firmware refuses (`error:20`): cncjs pauses
    // its workflow on the error, nothing after the line runs; then Stop.
    await load('f.nc');
    await mark('f_start');
    n = reads.length;
    command('gcode:start');
    await until(() => workflow === 'paused', 15000, 'job F: cncjs pauses on the error');
    await until(() => readsSince(n).some((l) => l.startsWith('error:')), 2000, 'job F: the error line');
    await waitStill(0.3, 10);
    await mark('f_paused');
    await sleep(1000);
    await mark('f_paused_end');
    command('gcode:stop', { force: true });
    await until(() => workflow === 'idle', 5000, 'job F: stopped');
    await sleep(1000);
    // G: a hard limit (X driven into its switch, soft limits off), then
    // Unlock ($X) and a jog off the switch, as a grbl user does.
    n = reads.length;
    writeln('$20=0');
    await until(() => readsSince(n).some((l) => l.startsWith('ok')), 5000, 'ok to $20=0');
    writeln('G91 G1 X-60 F600');
    await until(() => activeState === 'Alarm', 20000, 'the hard-limit alarm');
    await waitStill(0.3, 10);
    await mark('g_alarm');
    n = reads.length;
    command('unlock');
    await until(() => readsSince(n).some((l) => l.startsWith('ok')), 5000, 'ok to $X after the hard limit');
    await sleep(300);
    await mark('g_unlocked');
    writeln('$J=G91 X5 F600');
    await waitMoved('g_unlocked', 500, 10);
    await waitStill(0.3, 10);
    await mark('g_end');
    await until(() => activeState === 'Idle', 5000, 'Idle after the jog off the switch');
    writeln('G90');
    writeln('$20=1');
    await sleep(500);
  }

  // E: the port closed and opened again in the middle of a job (cncjs
  // restarted, the user reconnecting): opening the port resets the board
  // (auto-reset). The job is gone and a move is refused until homed.
  await load('a.nc');
  await mark('e_start');
  command('gcode:start');
  await until(() => workflow === 'running', 5000, 'job E: workflow running');
  await waitMoved('e_start', 150, 20);
  await mark('e_close');
  await new Promise((resolve) => socket.emit('close', port, () => resolve()));
  log('closed the port mid-job');
  n = reads.length;
  await new Promise((resolve, reject) => {
    socket.emit('open', port, { controllerType, baudrate: 250000 }, (err) => (err ? reject(new Error(`reopen: ${err}`)) : resolve()));
  });
  log(`opened ${port} again`);
  await until(() => readsSince(n).some((l) => l.startsWith('echo:reset cause')), 15000, 'the banner after reopening');
  await sleep(1000);
  await mark('e_reopened');
  n = reads.length;
  writeln('G91 G1 X1 F600');
  await until(() => readsSince(n).some((l) => l.startsWith('Error:not homed')), 5000, 'a move refused before homing');
  await sleep(1000);
  await mark('e_end');

  await new Promise((resolve) => socket.emit('close', port, () => resolve()));
  log('closed the port');
}

function fail(why) {
  out(`FAIL ${why}`);
  process.exit(1);
}

main().then(() => {
  out('DONE');
  process.exit(0);
}, (e) => fail(e && e.stack ? e.stack : String(e)));
