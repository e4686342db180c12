//! Stepper segment preparation and the Bresenham tick (SPEC §6).
