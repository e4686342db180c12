//! [`Vm::new`]: the firmware ELF (and the stock bootloader, if configured)
//! loaded into a fresh simavr ATmega2560, the shared state allocated and
//! every hook of the other files registered on the instance.

use super::inputs::drive_input;
use super::reset::reset_hook;
use super::simavr::{free, logger, no_sleep, zeroed_pod};
use super::uart::UartHost;
use super::{bad_opcode_notify, display, drivers, inputs, interrupts, outputs, sd_socket, timers, uart, uart_clock};
use super::{Inner, Vm, VmConfig, VmError};
use crate::boot;
use crate::elf::ElfSymbols;
use crate::isr::IsrTracker;
use crate::oled::Sh1106;
use crate::physics::Physics;
use crate::pins::Input;
use crate::recorder::Recorder;
use crate::report::{ResetKind, ResetRecord};
use simavr_ffi as ffi;
use std::ffi::{c_int, c_void, CString};
use std::path::PathBuf;
use std::sync::{Mutex, Once};

/// The last data address of the IO space as the VM runs it (see
/// `Vm::new`): UDR3, the chip's last register, is 0x136.
const IO_END: u16 = 0x137;

static LOGGER: Once = Once::new();
static LOAD_LOCK: Mutex<()> = Mutex::new(());

impl Vm {
    /// Loads the ELF into a fresh ATmega2560 and wires the machine around it.
    pub fn new(mut config: VmConfig) -> Result<Vm, VmError> {
        config.recorder.frequency_hz = config.frequency_hz;
        let path = config.elf.clone();
        if !path.exists() {
            return Err(VmError::Load(format!("{} does not exist (build it with `cargo fw`)", path.display())));
        }
        let symbols = ElfSymbols::load(&path).map_err(VmError::Load)?;
        LOGGER.call_once(|| {
            // SAFETY: installs a function pointer; simavr calls it with its own arguments.
            unsafe { ffi::avr_global_logger_set(Some(logger)) };
        });
        let cpath = CString::new(path.to_string_lossy().as_bytes()).map_err(|e| VmError::Load(e.to_string()))?;
        let _guard = LOAD_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: the name is a valid C string; returns null or a malloc'd mcu.
        let avr = unsafe { ffi::avr_make_mcu_by_name(c"atmega2560".as_ptr()) };
        if avr.is_null() {
            return Err(VmError::Load("simavr does not know atmega2560".into()));
        }
        // SAFETY: avr was just made; avr_init allocates flash/data and resets.
        unsafe { ffi::avr_init(avr) };
        let mut fw: Box<ffi::elf_firmware_t> = Box::new(zeroed_pod());
        // SAFETY: fw is zero-initialised as elf_read_firmware requires.
        let rc = unsafe { ffi::elf_read_firmware(cpath.as_ptr(), &mut *fw) };
        if rc != 0 {
            // SAFETY: avr is ours and not yet shared.
            unsafe {
                ffi::avr_terminate(avr);
                free(avr as *mut c_void);
            }
            return Err(VmError::Load(format!("simavr cannot read {}", path.display())));
        }
        fw.frequency = config.frequency_hz;
        // SAFETY: fw was filled by elf_read_firmware; load copies the chunks and frees them.
        unsafe {
            ffi::avr_load_firmware(avr, &mut *fw);
            for i in 0..fw.symbolcount as usize {
                free(*fw.symbol.add(i) as *mut c_void);
            }
            if !fw.symbol.is_null() {
                free(fw.symbol as *mut c_void);
            }
        }
        drop(_guard);
        // SAFETY: avr is ours, initialised and not running.
        if let Err(e) = unsafe { load_boot_section(avr, &config) } {
            // SAFETY: avr is ours and not yet shared.
            unsafe {
                ffi::avr_terminate(avr);
                free(avr as *mut c_void);
            }
            return Err(VmError::Load(e));
        }
        // simavr's ATmega2560 ends the IO space at 0x1FF (RAMSTART − 1),
        // but its table of IO callbacks holds 280 registers (data addresses
        // 0x20..=0x137): a store to the reserved extended IO at
        // 0x138..=0x1FF read a "callback" past the table's end and the VM
        // crashed (SIGSEGV: code run from the middle of the firmware after a
        // watchdog reset without the landing pad, tests/bootloader.rs, did
        // such a store). The chip's last register is UDR3 at 0x136, so the
        // IO space ends at 0x137 here: the reserved bytes above it are plain
        // memory, where the chip ignores writes and reads 0. Set after the
        // ELF is loaded (simavr places data chunks relative to `ioend`).
        // SAFETY: avr is ours, initialised and not running.
        unsafe { (*avr).ioend = IO_END };

        let recorder = Recorder::new(config.recorder.clone(), &config.machine);
        let mut physics = Physics::new(config.machine.clone());
        physics.set_clock_hz(config.frequency_hz as f64);
        let inner = Box::into_raw(Box::new(Inner {
            avr,
            uart: std::ptr::null_mut(),
            cycle_base: 0,
            batch_cycles: config.batch_cycles.max(1),
            max_nesting: config.max_interrupt_nesting,
            stop_on_bad_opcode: config.stop_on_bad_opcode,
            recorder,
            physics,
            isr: IsrTracker::default(),
            host: UartHost::default(),
            pins: config.pins,
            pokes: config.poke_after_reset.clone(),
            levels: [None; Input::COUNT],
            input_irqs: [std::ptr::null_mut(); Input::COUNT],
            output_irqs: Vec::new(),
            orig_reset: None,
            reset_seen: false,
            resets: vec![ResetRecord { cycle: 0, kind: ResetKind::PowerOn }],
            event: false,
            fatal: None,
            stop_armed_at: None,
            log: Vec::new(),
            spindle_duty: 0.0,
            spindle_history: Vec::new(),
            coolant: false,
            coolant_history: Vec::new(),
            oled: Sh1106::new(),
            oled_selected: false,
            twi_input: std::ptr::null_mut(),
            sd: None,
            sd_selected: false,
            spi_input: std::ptr::null_mut(),
            switch_timer_at: None,
            in_switch_timer: false,
        }));
        let param = inner as *mut c_void;

        // SAFETY: avr is a live, initialised instance owned by this
        // function (the whole block); every IRQ pointer comes from simavr's
        // own lookup and is checked for null; `param`/hook pointers stay
        // valid until Vm::drop terminates the instance.
        let hooks = unsafe {
            (*avr).custom.data = param;
            (*avr).sleep = Some(no_sleep);
            (*avr).run_cycle_limit = config.batch_cycles.max(1);
            (*inner).orig_reset = (*avr).reset;
            (*avr).reset = Some(reset_hook);

            if !uart::attach(avr, inner) {
                drop(Box::from_raw(inner));
                ffi::avr_terminate(avr);
                free(avr as *mut c_void);
                return Err(VmError::Load("simavr has no UART0".into()));
            }
            let hooks = drivers::attach(avr, inner);
            inputs::attach(avr, inner);
            for &(addr, v) in &(*inner).pokes {
                *(*avr).data.add(addr as usize) = v;
            }
            for input in Input::ALL {
                drive_input(&mut *inner, input, true);
            }
            interrupts::attach(avr, inner);
            let bad = ffi::avr_get_core_irq(avr, ffi::AVR_CORE_BAD_OPCODE as c_int);
            if !bad.is_null() {
                ffi::avr_irq_register_notify(bad, Some(bad_opcode_notify), param);
            }
            outputs::attach(avr, inner);
            display::attach(avr, inner);
            sd_socket::attach(avr, inner);
            hooks
        };

        // SAFETY: avr is live and not running; the wraps are kept in the Vm
        // and dropped after the instance (Vm::drop).
        let timer_wraps = unsafe { timers::wrap(avr, config.fix_tcnt_on_clock_start) };
        // SAFETY: as above; `uart` is the instance's UART0 (found by uart::attach).
        let uart_wraps = unsafe { uart_clock::wrap(avr, (*inner).uart) };

        Ok(Vm { avr, inner, hooks, timer_wraps, uart_wraps, config, symbols, wall_start: std::time::Instant::now() })
    }

    /// A VM for `elf` with the default machine.
    pub fn with_elf(elf: impl Into<PathBuf>) -> Result<Vm, VmError> {
        Vm::new(VmConfig::new(elf))
    }
}

/// Erases the application space if asked, then loads the bootloader with
/// the fuses and lock byte of a board as sold and points the reset vector
/// (BOOTRST) at it.
///
/// SAFETY: `avr` must be a live, initialised instance that is not running.
unsafe fn load_boot_section(avr: *mut ffi::avr_t, config: &VmConfig) -> Result<(), String> {
    // SAFETY: flash has flashend + 1 bytes; the caller owns the instance.
    unsafe {
        let flash = std::slice::from_raw_parts_mut((*avr).flash, (*avr).flashend as usize + 1);
        if config.blank_application {
            flash[..boot::BOOT_START as usize].fill(0xFF);
        }
        let Some(hex) = &config.bootloader else { return Ok(()) };
        for chunk in boot::read_ihex(hex)? {
            let (a, n) = (chunk.addr as usize, chunk.bytes.len());
            if a < boot::BOOT_START as usize || a + n > flash.len() {
                return Err(format!("{}: bytes at 0x{a:05x} outside the boot section", hex.display()));
            }
            flash[a..a + n].copy_from_slice(&chunk.bytes);
        }
        (*avr).codeend = (*avr).flashend;
        (*avr).reset_pc = boot::BOOT_START;
        (*avr).pc = boot::BOOT_START;
        for (i, &f) in boot::STOCK_FUSES.iter().enumerate() {
            (*avr).fuse[i] = f;
        }
        (*avr).lockbits = boot::STOCK_LOCK;
    }
    Ok(())
}
