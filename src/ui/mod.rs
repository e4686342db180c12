//! Standalone UI (docs/SPEC.md §9): SH1106 status screen and menu on the rotary
//! encoder, and SD card jobs.
//!
//! Everything here is plain logic, unit-tested on the host; `board` does
//! the I2C/SPI transfers and the encoder sampling, `firmware.rs` wires them:
//!
//! ```text
//!  Timer0 1 kHz tick ─► encoder::Decoder (quadrature → detents, button)
//!  main loop idle    ─► menu::Ui::step (detents, press) ─► Cmd (hold, abort, jog, run file ...)
//!                    ─► render one 32-column slice of one page ─► SH1106 over I2C
//!  SD card           ─► sd::SdJob (lines) ─► Machine::run_job_line
//! ```
//!
//! - [`flash`], [`text`], [`font`]: strings and the 5x7 font, kept in flash;
//! - [`render`]: 8 text lines of 25 characters, rendered page by page
//!   (no 1 KiB frame buffer: one 32-byte slice at a time);
//! - [`menu`]: the menu tree as data and its state machine;
//! - [`encoder`]: quadrature decoding and button debouncing;
//! - [`card`]: the SD card as a trait: names, entries, folders, errors;
//! - [`sd`]: SD jobs and M20–M29 (and run from line's scan);
//! - [`resume`]: run from line's EEPROM record of the last job and the line it reached;
//! - [`files`]: the Files screen's sorted list of folders and files.

pub mod card;
pub mod encoder;
pub mod files;
pub mod flash;
pub mod font;
pub mod menu;
pub mod render;
pub mod resume;
pub mod sd;
pub mod text;
