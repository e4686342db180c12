//! G-code (SPEC §5): word-address parser and interpreter.
