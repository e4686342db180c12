//! Automatic tool changer (SPEC §7): the T/M6 tool-change state machine, the
//! G201–G205 carousel commands and the EEPROM record of which tool is where.
//!
//! Not implemented yet (its own issue). It will sit between the G-code
//! interpreter and the planner: the interpreter hands it `Tn`/`M6`, it drives
//! moves through the planner and the carousel through the E0 axis.
