//! What a run leaves behind: the [`Report`] (axes, ISR times, violations,
//! UART, resets, errors), its JSON, the step trace as CSV, and simavr's own
//! warnings and errors.

use super::Vm;
use crate::host::StreamReport;
use crate::pins::Axis;
use crate::report::{AxisReport, Report, UartReport};
use std::path::Path;

impl Vm {
    /// simavr's warnings and errors for this instance (e.g. RX overruns).
    pub fn simavr_log(&self) -> &[String] {
        &self.inner().log
    }

    /// Summary of the run so far. `job` is the stream report, if any.
    pub fn report(&self, job: Option<&StreamReport>) -> Report {
        let inner = self.inner();
        let rec = &inner.recorder;
        let axes = Axis::ALL
            .iter()
            .map(|&a| {
                let s = rec.axis_stats(a);
                AxisReport {
                    axis: a,
                    steps_pos: s.steps_pos,
                    steps_neg: s.steps_neg,
                    steps_while_disabled: s.steps_while_disabled,
                    final_position_steps: s.position,
                    // Physical Z steps count down from the top switch; the
                    // firmware's machine Z (and this figure) has +Z up.
                    final_position_mm: s.position as f64 / self.config.machine.steps_per_mm[a.index()]
                        * if a == Axis::Z { -1.0 } else { 1.0 },
                    peak_rate_hz: s.peak_rate_hz,
                    peak_rate_windowed_hz: s.peak_rate_windowed_hz,
                    max_accel_steps_per_s2: s.max_accel_steps_per_s2,
                    max_accel_mm_per_s2: s.max_accel_steps_per_s2.map(|x| x / self.config.machine.steps_per_mm[a.index()]),
                }
            })
            .collect();
        let mut errors: Vec<String> = inner.fatal.iter().map(|e| e.to_string()).collect();
        if let Some(j) = job {
            if j.timed_out {
                errors.push(format!("stream timed out after {:.3} s", j.duration_s.max(0.0)));
            }
        }
        let sim_time_s = self.seconds();
        let wall = self.wall_seconds();
        Report {
            elf: self.config.elf.display().to_string(),
            job_time_s: job.map_or(sim_time_s, |j| j.duration_s),
            sim_time_s,
            wall_time_s: wall,
            sim_speed: if wall > 0.0 { sim_time_s / wall } else { 0.0 },
            axes,
            stepper_isr: self.stepper_isr_stats(),
            isr: self.all_isr_stats(),
            max_interrupt_depth: inner.isr.max_depth(),
            stack_high_water_bytes: self.stack_high_water_bytes(),
            violation_count: rec.violation_count(),
            violations: rec.violations().to_vec(),
            uart: UartReport {
                bytes_to_chip: inner.host.bytes_to_chip,
                bytes_from_chip: inner.host.out.len() as u64,
                rx_dropped: inner.host.rx_dropped,
                rx_would_overrun: inner.host.rx_deep,
                simavr_messages: inner.log.iter().filter(|m| m.contains("UART")).cloned().collect(),
            },
            resets: inner.resets.clone(),
            spindle_on_at_end: self.spindle_on(),
            errors,
            stream: job.map(|j| StreamReport { received: Vec::new(), ..j.clone() }),
        }
    }

    /// Writes [`Vm::report`] as pretty JSON.
    pub fn write_json(&self, path: impl AsRef<Path>, job: Option<&StreamReport>) -> std::io::Result<()> {
        self.report(job).write_json(path)
    }

    /// Writes the step trace as CSV: `cycle,time_s,axis,position`.
    pub fn write_trace_csv(&self, path: impl AsRef<Path>) -> std::io::Result<()> {
        crate::report::write_trace_csv(path, self.recorder().trace(), self.config.frequency_hz)
    }
}
