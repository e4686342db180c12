//! Calling one routine of the loaded ELF, as a test harness for assembly
//! routines: the registers are set, a return address is pushed, and the
//! core runs one instruction at a time, interrupts off, until the routine
//! returns. The registers and SREG it leaves are read back; nothing else of
//! the machine is restored, so a VM used for calls is used only for that.

use super::{Vm, VmError};
use simavr_ffi as ffi;
use std::os::raw::c_int;

/// Data-space address of the stack pointer (SPL; SPH follows, ATmega2560
/// datasheet §7.6).
const SPL: u16 = 0x5D;
/// Where a call's stack starts: the top of SRAM less a margin (no interrupt
/// runs and nothing else of the firmware is live during calls).
const CALL_STACK_TOP: u16 = 0x2100;
/// Byte address the routine returns to: the last word of flash, made an
/// `rjmp .-2`.
const RETURN_ADDR: u32 = 0x3_FFFE;

impl Vm {
    /// Calls the routine at byte address `addr` with `regs` (register
    /// number, value) written first, the other registers as the last call
    /// (or the firmware) left them, r1 = 0 and interrupts off. Returns the
    /// cycles from the first instruction to the `ret` included; an error
    /// after `max_cycles`. Read the results with [`Vm::reg`] and
    /// [`Vm::sreg_t`].
    pub fn call(&mut self, addr: u32, regs: &[(u8, u8)], max_cycles: u64) -> Result<u64, VmError> {
        self.write_ram(1, &[0]);
        for &(r, v) in regs {
            assert!(r < 32, "r{r}");
            self.write_ram(r as u16, &[v]);
        }
        // The return address, pushed as `call` does on a 3-byte PC: the
        // word address, low byte at SP, then SP moves down by 3.
        let ret = RETURN_ADDR >> 1;
        let sp = CALL_STACK_TOP - 3;
        self.write_ram(sp + 1, &[(ret >> 16) as u8, (ret >> 8) as u8, ret as u8]);
        self.write_ram(SPL, &sp.to_le_bytes());
        let avr = self.avr;
        // SAFETY: avr is live and not running; flash has flashend + 1 bytes
        // (≥ RETURN_ADDR + 2 on the ATmega2560).
        unsafe {
            *(*avr).flash.add(RETURN_ADDR as usize) = 0xFF;
            *(*avr).flash.add(RETURN_ADDR as usize + 1) = 0xCF;
            (*avr).sreg[7] = 0;
            (*avr).pc = addr;
            (*avr).state = ffi::cpu_Running as c_int;
            let limit = (*avr).run_cycle_limit;
            (*avr).run_cycle_limit = 1;
            let start = (*avr).cycle;
            let result = loop {
                if (*avr).pc == RETURN_ADDR {
                    break Ok((*avr).cycle - start);
                }
                if (*avr).cycle - start > max_cycles {
                    break Err(VmError::Timeout { what: format!("call of {addr:#x}"), waited_s: 0.0 });
                }
                let state = ffi::avr_run(avr);
                if state != ffi::cpu_Running as c_int {
                    break Err(VmError::Crashed { pc: (*avr).pc, cycle: (*avr).cycle });
                }
            };
            (*avr).run_cycle_limit = limit;
            result
        }
    }

    /// Register `r` (0..32).
    pub fn reg(&self, r: u8) -> u8 {
        assert!(r < 32, "r{r}");
        self.inner().read(r as u16)
    }

    /// SREG's T flag.
    pub fn sreg_t(&self) -> bool {
        // SAFETY: avr is live.
        unsafe { (*self.avr).sreg[6] != 0 }
    }
}
