//! Standalone UI (SPEC §9): SH1106 status screen, encoder menu and SD jobs.
//!
//! Not implemented yet (its own issue). The menu model and page-by-page
//! rendering will live here; the I2C/SPI transfers live in `board`.
