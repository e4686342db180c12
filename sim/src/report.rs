//! The run report (JSON) and the step trace (CSV), docs/SPEC.md §12 "Outputs".

use crate::host::StreamReport;
use crate::isr::IsrStats;
use crate::pins::Axis;
use crate::recorder::{TracePoint, Violation};
use serde::Serialize;
use std::io::Write;
use std::path::Path;

/// How the chip was last reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ResetKind {
    PowerOn,
    External,
    Watchdog,
}

/// One reset and when it happened (VM cycle).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct ResetRecord {
    pub cycle: u64,
    pub kind: ResetKind,
}

/// One axis in the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AxisReport {
    pub axis: Axis,
    pub steps_pos: u64,
    pub steps_neg: u64,
    pub steps_while_disabled: u64,
    /// Physical steps from the switch (Z counts downward from its top switch).
    pub final_position_steps: i64,
    /// The machine coordinate as the firmware reports it: mm, +Z up (Z is
    /// the negated physical distance below the top switch).
    pub final_position_mm: f64,
    /// From the shortest interval between rising edges, Hz.
    pub peak_rate_hz: f64,
    /// Most edges in a 1 ms window, Hz.
    pub peak_rate_windowed_hz: f64,
    /// Smoothed, see `Recorder::max_accel`.
    pub max_accel_steps_per_s2: Option<f64>,
    pub max_accel_mm_per_s2: Option<f64>,
}

/// Host link figures.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct UartReport {
    pub bytes_to_chip: u64,
    pub bytes_from_chip: u64,
    /// Flood bytes lost (hardware 2-byte FIFO model).
    pub rx_dropped: u64,
    /// Paced bytes that met ≥ 2 unread bytes (overruns without flow control).
    pub rx_would_overrun: u64,
    /// simavr's UART warnings/errors.
    pub simavr_messages: Vec<String>,
}

/// Everything the VM measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    pub elf: String,
    /// Simulated seconds from the job's first byte to its last `ok`
    /// (the whole run if there was no job).
    pub job_time_s: f64,
    /// Simulated seconds since power-on.
    pub sim_time_s: f64,
    /// Wall-clock seconds since the VM was created.
    pub wall_time_s: f64,
    /// Simulated seconds per wall second.
    pub sim_speed: f64,
    pub axes: Vec<AxisReport>,
    /// TIMER1_COMPA, cycles including the hardware's entry/RETI overhead.
    pub stepper_isr: Option<IsrStats>,
    pub isr: Vec<IsrStats>,
    pub max_interrupt_depth: u32,
    pub stack_high_water_bytes: Option<u32>,
    pub violation_count: u64,
    pub violations: Vec<Violation>,
    pub uart: UartReport,
    pub resets: Vec<ResetRecord>,
    pub spindle_on_at_end: bool,
    /// Crash, nesting overflow, timeout.
    pub errors: Vec<String>,
    pub stream: Option<StreamReport>,
}

impl Report {
    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\":\"{e}\"}}"))
    }

    /// Writes [`Report::to_json`], creating parent directories.
    pub fn write_json(&self, path: impl AsRef<Path>) -> std::io::Result<()> {
        let path = path.as_ref();
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        std::fs::write(path, self.to_json())
    }

    /// True if nothing went wrong: no violation, no error.
    pub fn clean(&self) -> bool {
        self.violation_count == 0 && self.errors.is_empty()
    }

    /// A few aligned lines for people.
    pub fn human(&self) -> String {
        let mut s = String::new();
        let mut line = |k: &str, v: String| s.push_str(&format!("{k:<22}{v}\n"));
        line("firmware", self.elf.clone());
        line("job time", format!("{:.3} s simulated", self.job_time_s));
        line(
            "simulation speed",
            format!("{:.2} s simulated / wall s ({:.3} s in {:.3} s)", self.sim_speed, self.sim_time_s, self.wall_time_s),
        );
        for a in &self.axes {
            line(
                &format!("axis {}", a.axis),
                format!(
                    "+{:<7} -{:<7} end {:>9.3} ({:>7} steps)  peak {:>8.0} Hz  accel {}",
                    a.steps_pos,
                    a.steps_neg,
                    a.final_position_mm,
                    a.final_position_steps,
                    a.peak_rate_hz,
                    a.max_accel_steps_per_s2.map_or("-".to_string(), |x| format!("{x:.0} steps/s²")),
                ),
            );
        }
        line(
            "stepper ISR (vect 17)",
            self.stepper_isr.map_or("never ran".into(), |i| {
                format!("n={} min={} mean={:.1} max={} cycles", i.count, i.min_cycles, i.mean_cycles, i.max_cycles)
            }),
        );
        line("max IRQ nesting", self.max_interrupt_depth.to_string());
        line("stack high-water", self.stack_high_water_bytes.map_or("unknown (no paint)".into(), |b| format!("{b} bytes")));
        line("uart", format!("{} bytes in, {} out, {} dropped", self.uart.bytes_to_chip, self.uart.bytes_from_chip, self.uart.rx_dropped));
        if let Some(j) = &self.stream {
            line(
                "stream",
                format!(
                    "{} lines, {} sent, {} ok, {} errors, {} resends{}",
                    j.lines_total,
                    j.lines_sent,
                    j.oks,
                    j.errors.len(),
                    j.resends,
                    if j.timed_out { ", TIMED OUT" } else { "" }
                ),
            );
        }
        line("violations", self.violation_count.to_string());
        for v in self.violations.iter().take(10) {
            line("", format!("{} {:?} at {:.6} s: measured {} (limit {})", v.axis, v.kind, v.time_s, v.measured, v.limit));
        }
        for e in &self.errors {
            line("ERROR", e.clone());
        }
        s
    }
}

/// Writes the trace as `cycle,time_s,axis,position`, creating parent directories.
pub fn write_trace_csv(path: impl AsRef<Path>, trace: &[TracePoint], frequency_hz: u32) -> std::io::Result<()> {
    let path = path.as_ref();
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(w, "cycle,time_s,axis,position")?;
    for t in trace {
        writeln!(w, "{},{:.9},{},{}", t.cycle, t.cycle as f64 / frequency_hz as f64, t.axis, t.position)?;
    }
    w.flush()
}
