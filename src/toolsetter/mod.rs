//! Optical tool setter (SPEC §8): G37 length/diameter measurement, broken-tool
//! check and reference calibration, as a state machine fed by the probe latch.
//!
//! Not implemented yet (its own issue). The trip position will be latched by
//! the stepper ISR in `board` on the PD2 input edge and handed to this module.
