//! Host protocol (SPEC §4).
