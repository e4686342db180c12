//! `profile`: a sampling profiler of the firmware in the virtual machine.
//!
//! ```text
//! cargo run -p sim --release --bin profile -- [--elf PATH] [--every CYCLES] [JOB.gcode]
//! ```
//!
//! Boots the ELF, streams the job ping-pong (default: the benchmark's 2,000
//! moves of 0.1 mm at F3000) and samples the program counter every `CYCLES`
//! simulated cycles (default 97, prime so it does not beat with the timer).
//! Prints the share of CPU time per function (by ELF symbol; inlined code
//! counts in its caller). Interrupt handlers show as `__vector_N`.
//!
//! `--trace FROM:N` instead single-steps the lines FROM..FROM+N (counted by
//! their `ok`) and prints exact inclusive and self cycles per function.
//! `--sd` runs the job from a FAT16 card (M23/M24) instead of the serial
//! line; `--trace FROM:N` then starts FROM ms after M24 and covers N lines
//! (counted as entries into `Planner::queue_block`).
//! `--feed F` runs the default job at F mm/min (the axes' M203 limit
//! raised above 3000), to profile it where the CPU is the limit; `--accel
//! A` at A mm/s² on X and Y (the benchmark's CPU row: F12000, 5000).
//! `--hist NAME` (with `--trace`; `?` for code no symbol covers) also prints the traced cycles per
//! instruction address inside the functions whose name contains NAME, to
//! read against `avr-objdump -d`.
//! `--under NAME` (with `--trace`) counts the self cycles only while a
//! function whose name contains NAME is on the stack: what it costs,
//! callee by callee (interrupts that land in it included).

use sim::host::prepare_gcode;
use sim::{CardKind, FatKind, SdCard, SdImage, Vm, VmConfig};
use std::collections::HashMap;
use std::path::PathBuf;

fn demangle(s: &str) -> String {
    // Crude v0/legacy demangling: the length-prefixed identifiers, joined.
    let b = s.as_bytes();
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() && (i == 0 || !b[i - 1].is_ascii_digit()) {
            let mut j = i;
            let mut n = 0usize;
            while j < b.len() && b[j].is_ascii_digit() {
                n = n * 10 + (b[j] - b'0') as usize;
                j += 1;
            }
            if j < b.len() && b[j] == b'_' {
                j += 1;
            }
            if n > 0 && j + n <= b.len() && (b[j].is_ascii_alphabetic() || b[j] == b'_') {
                let id = &s[j..j + n];
                if !id.starts_with('h') || id.len() != 17 {
                    out.push(id.to_string());
                }
                i = j + n;
                continue;
            }
        }
        i += 1;
    }
    if out.is_empty() {
        s.to_string()
    } else {
        out.join("::")
    }
}

fn main() {
    let mut elf = VmConfig::default_elf_path();
    let mut every = 97u64;
    let mut window = 0usize;
    // Exact inclusive cycles per function for the lines [from, from + n) (ok'd).
    let mut trace: Option<(usize, usize)> = None;
    let mut job: Option<PathBuf> = None;
    let mut sd = false;
    let mut hist_name: Option<String> = None;
    let mut under_name: Option<String> = None;
    let mut feed = 3000.0f64;
    let mut accel: Option<f64> = None;
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--elf" => elf = it.next().expect("--elf PATH").into(),
            "--every" => every = it.next().expect("--every N").parse().expect("number"),
            "--count" => window = it.next().expect("--count BYTES").parse().expect("number"),
            "--sd" => sd = true,
            "--hist" => hist_name = Some(it.next().expect("--hist NAME")),
            "--under" => under_name = Some(it.next().expect("--under NAME")),
            "--feed" => feed = it.next().expect("--feed F").parse().expect("number"),
            "--accel" => accel = Some(it.next().expect("--accel A").parse().expect("number")),
            "--trace" => {
                let v = it.next().expect("--trace FROM:N");
                let (a, b) = v.split_once(':').expect("FROM:N");
                trace = Some((a.parse().expect("number"), b.parse().expect("number")));
            }
            s => job = Some(s.into()),
        }
    }
    let lines: Vec<String> = match job {
        Some(p) => prepare_gcode(&std::fs::read_to_string(p).expect("job")),
        None => {
            let mut v = vec!["M999".to_string()];
            if let Some(a) = accel {
                v.push(format!("M201 X{a} Y{a}"));
            }
            v.extend(sim::circle::setup(feed));
            v.extend(sim::circle::moves());
            v
        }
    };
    let mut vm = Vm::new(VmConfig::new(&elf)).expect("load");
    vm.wait_for_start(3.0).expect("start");
    vm.run_for(0.05).unwrap();
    vm.take_lines();
    let mut syms: Vec<(u32, u32, String)> = vm
        .symbols()
        .find("")
        .into_iter()
        .filter(|s| s.space == sim::elf::Space::Flash && s.size > 0)
        .map(|s| (s.addr, s.size, demangle(&s.name)))
        .collect();
    syms.sort();
    // Flash image, to recognise return addresses on the stack (the word
    // before one is a CALL/RCALL/ICALL/EICALL).
    let flash = {
        use object::{Object, ObjectSection};
        let data = std::fs::read(&elf).expect("elf");
        let f = object::File::parse(&*data).expect("elf");
        let mut img = vec![0u8; 0x40000];
        for sec in f.sections() {
            if sec.name() == Ok(".text") {
                if let Ok(d) = sec.data() {
                    let a = sec.address() as usize;
                    if a + d.len() <= img.len() {
                        img[a..a + d.len()].copy_from_slice(d);
                    }
                }
            }
        }
        img
    };
    let word = |a: u32| -> u16 {
        let a = a as usize;
        if a + 1 < flash.len() {
            u16::from_le_bytes([flash[a], flash[a + 1]])
        } else {
            0
        }
    };
    let after_call = |ret: u32| -> bool {
        if ret < 4 {
            return false;
        }
        let w2 = word(ret - 2);
        let w4 = word(ret - 4);
        (w4 & 0xFE0E) == 0x940E || (w2 & 0xF000) == 0xD000 || w2 == 0x9509 || w2 == 0x9519
    };
    let lookup = |pc: u32| -> Option<usize> {
        let k = syms.partition_point(|s| s.0 <= pc);
        if k > 0 && pc < syms[k - 1].0 + syms[k - 1].1 {
            Some(k - 1)
        } else {
            None
        }
    };
    let starts: HashMap<u32, usize> = syms.iter().enumerate().map(|(i, s)| (s.0, i)).collect();
    let under: Option<Vec<bool>> = under_name.as_ref().map(|n| syms.iter().map(|s| s.2.contains(n.as_str())).collect());
    // From SD: the first lines (setup) over serial, the rest as a file.
    let mut lines = lines;
    let mut sd_start_cycles = 0u64;
    let queue_block = syms.iter().position(|s| s.2.ends_with("Planner::queue_block"));
    if sd {
        let setup = lines.iter().position(|l| l == "M400").map_or(0, |i| i + 1);
        let body: Vec<String> = lines.split_off(setup);
        for l in &lines {
            vm.send_line(l);
            vm.wait_line(|x| x == "ok", 30.0).expect("ok");
        }
        lines.clear();
        let text = body.join("\n") + "\n";
        vm.insert_sd(SdCard::new(SdImage::new(FatKind::Fat16).file("PROFILE.NC", text.as_bytes()).build(), CardKind::Sdhc));
        vm.send_line("M23 PROFILE.NC");
        vm.wait_line(|x| x == "ok", 30.0).expect("M23");
        vm.take_lines();
        vm.send_line("M24");
        sd_start_cycles = vm.cycles();
    }
    let mut blocks = 0usize;
    let mut tstack: Vec<(usize, u64, u32)> = Vec::new();
    let mut tincl: HashMap<usize, (u64, u64)> = HashMap::new();
    let mut tself: HashMap<Option<usize>, u64> = HashMap::new();
    let mut prev_pc_fn: Option<usize> = lookup(vm.pc());
    let mut prev_pc = vm.pc();
    let mut hist: HashMap<u32, u64> = HashMap::new();
    let mut callers: HashMap<String, (u64, u64)> = HashMap::new();
    let mut oks = 0usize;
    let mut traced_cycles = 0u64;
    let mut incl: HashMap<String, u64> = HashMap::new();
    let mut hits: HashMap<String, u64> = HashMap::new();
    let mut total = 0u64;
    let t0 = vm.cycles();
    // Ping-pong (window 0) or character counting (at most `window` bytes unacknowledged).
    let mut next = 0;
    let mut in_flight: std::collections::VecDeque<usize> = Default::default();
    while next < lines.len() || !in_flight.is_empty() || (sd && trace.is_some_and(|(_, n)| blocks < n)) {
        while next < lines.len() {
            let len = lines[next].len() + 1;
            let bytes: usize = in_flight.iter().sum();
            if !(in_flight.is_empty() || (window > 0 && bytes + len <= window)) {
                break;
            }
            vm.send_line(&lines[next]);
            in_flight.push_back(len);
            next += 1;
        }
        if let Some((from, n)) = trace {
            let in_window =
                if sd { vm.cycles() >= sd_start_cycles + from as u64 * 16_000 && blocks < n } else { oks >= from && oks < from + n };
            if in_window {
                let c0 = vm.cycles();
                vm.run_cycles(1).expect("run");
                let c = vm.cycles();
                traced_cycles += c - c0;
                let pc = vm.pc();
                let sp = vm.read_u16(0x5D) as u32;
                // Self time: the cycles of the instruction just run, charged
                // to the function the PC was in before it ran.
                let counted = match &under {
                    Some(u) => tstack.iter().any(|f| u[f.0]) || prev_pc_fn.is_some_and(|k| u[k]),
                    None => true,
                };
                if counted {
                    *tself.entry(prev_pc_fn).or_default() += c - c0;
                }
                if let Some(h) = &hist_name {
                    // `?`: the addresses no symbol covers.
                    let hit = match prev_pc_fn {
                        Some(k) => syms[k].2.contains(h.as_str()),
                        None => h == "?",
                    };
                    if hit {
                        *hist.entry(prev_pc).or_default() += c - c0;
                    }
                }
                prev_pc_fn = lookup(pc);
                prev_pc = pc;
                while let Some(&(k, entry, fsp)) = tstack.last() {
                    if sp > fsp {
                        tstack.pop();
                        if !tstack.iter().any(|f| f.0 == k) {
                            let e = tincl.entry(k).or_default();
                            e.0 += c - entry;
                            e.1 += 1;
                        }
                    } else {
                        break;
                    }
                }
                if let Some(&k) = starts.get(&pc) {
                    tstack.push((k, c, sp));
                    if Some(k) == queue_block {
                        blocks += 1;
                    }
                    // Who calls the copy/fill/float routines and the main loop's
                    // turn (`idle`, `wait_step`: from a wait or the loop), and how much.
                    let name = &syms[k].2;
                    if matches!(
                        name.as_str(),
                        "memcpy"
                            | "memset"
                            | "__divsf3"
                            | "__mulsf3"
                            | "__wrap___mulsf3"
                            | "__wrap___addsf3"
                            | "__wrap___subsf3"
                            | "sqrt"
                            | "r::mill::math::sqrt::sqrt_1ulp"
                            | "__udivmodsi4"
                            | "__mulsi3"
                            | "__floatsisf"
                            | "__floatunsisf"
                            | "__fixsfsi"
                            | "__fixunssfsi"
                            | "__addsf3"
                            | "__subsf3"
                    ) || name.contains("Machine::idle")
                        || name.contains("Machine::wait_step")
                    {
                        let b = vm.read_ram((sp + 1) as u16, 3);
                        let ret = (((b[0] as u32) << 16) | ((b[1] as u32) << 8) | b[2] as u32) * 2;
                        let caller = match lookup(ret) {
                            Some(j) => syms[j].2.clone(),
                            None => format!("?{ret:#x}"),
                        };
                        let n = vm.read_u16(20) as u64; // r21:r20 = length for memcpy/memset
                        let e = callers.entry(format!("{name} <- {caller}")).or_insert((0u64, 0u64));
                        e.0 += 1;
                        e.1 += n;
                    }
                }
                for l in vm.take_lines() {
                    if l == "ok" {
                        in_flight.pop_front();
                        oks += 1;
                    }
                }
                continue;
            }
        }
        vm.run_cycles(every).expect("run");
        let pc = vm.pc();
        let name = match lookup(pc) {
            Some(k) => syms[k].2.clone(),
            None => format!("?{pc:#x}"),
        };
        *hits.entry(name.clone()).or_default() += 1;
        total += 1;
        // Inclusive: every function with a return address on the stack.
        let sp = vm.read_u16(0x5D) as u32;
        let mut seen = vec![name];
        let mut a = sp + 1;
        while a + 2 <= 0x21FF {
            let b = vm.read_ram(a as u16, 3);
            let ret = (((b[0] as u32) << 16) | ((b[1] as u32) << 8) | b[2] as u32) * 2;
            if b[0] <= 1 && after_call(ret) {
                if let Some(k) = lookup(ret) {
                    let n = &syms[k].2;
                    if !seen.contains(n) {
                        seen.push(n.clone());
                    }
                    a += 3;
                    continue;
                }
            }
            a += 1;
        }
        for n in seen {
            *incl.entry(n).or_default() += 1;
        }
        for l in vm.take_lines() {
            if l == "ok" {
                in_flight.pop_front();
                oks += 1;
            }
        }
    }
    let secs = (vm.cycles() - t0) as f64 / 16e6;
    if let Some((from, n)) = trace {
        let mut v: Vec<_> = tincl.into_iter().collect();
        v.sort_by_key(|e| std::cmp::Reverse(e.1 .0));
        println!(
            "-- exact inclusive cycles, lines {from}..{} ({} cycles traced, {} per line) --",
            from + n,
            traced_cycles,
            traced_cycles / n as u64
        );
        println!("{:>12} {:>8} {:>10} {:>8}  function", "cycles/line", "calls", "per call", "%");
        for (k, (c, calls)) in v.iter().take(60) {
            println!(
                "{:>12} {:>8} {:>10} {:>7.1}%  {}",
                c / n as u64,
                calls,
                c / calls.max(&1),
                100.0 * *c as f64 / traced_cycles as f64,
                syms[*k].2
            );
        }
        let mut v: Vec<_> = tself.into_iter().collect();
        v.sort_by_key(|e| std::cmp::Reverse(e.1));
        println!("-- exact self cycles (instructions run in the function itself) --");
        println!("{:>12} {:>8}  function", "cycles/line", "%");
        for (k, c) in v.iter().take(70) {
            let name = match k {
                Some(k) => syms[*k].2.clone(),
                None => "?".to_string(),
            };
            println!("{:>12} {:>7.1}%  {}", c / n as u64, 100.0 * *c as f64 / traced_cycles as f64, name);
        }
        if hist_name.is_some() {
            let mut v: Vec<_> = hist.into_iter().collect();
            v.sort();
            println!("-- cycles per line by instruction address (--hist) --");
            for (pc, c) in v {
                println!("{:>8x} {:>8.1}", pc, c as f64 / n as f64);
            }
        }
        let mut v: Vec<_> = callers.into_iter().collect();
        v.sort_by_key(|e| std::cmp::Reverse(e.1 .0));
        println!("-- callers (calls per line, mean r21:r20 = bytes for memcpy/memset) --");
        for (k, (calls, bytes)) in v.iter().take(40) {
            println!("{:>8.2} {:>8}  {k}", *calls as f64 / n as f64, bytes / calls.max(&1));
        }
        return;
    }
    let mut v: Vec<_> = hits.into_iter().collect();
    v.sort_by_key(|e| std::cmp::Reverse(e.1));
    println!("{} lines in {:.3} s simulated, {} samples every {} cycles", lines.len(), secs, total, every);
    println!("-- self --");
    for (name, n) in v.iter().take(30) {
        println!("{:6.2} %  {:>10} cycles/line  {name}", 100.0 * *n as f64 / total as f64, (*n * every) / lines.len() as u64);
    }
    let mut v: Vec<_> = incl.into_iter().collect();
    v.sort_by_key(|e| std::cmp::Reverse(e.1));
    println!("-- inclusive (stack scan; approximate) --");
    for (name, n) in v.iter().take(45) {
        println!("{:6.2} %  {:>10} cycles/line  {name}", 100.0 * *n as f64 / total as f64, (*n * every) / lines.len() as u64);
    }
}
