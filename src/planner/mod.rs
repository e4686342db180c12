//! Motion planner (SPEC §6).
