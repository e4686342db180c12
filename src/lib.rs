//! Mill firmware core: the pure logic, host-testable.
#![cfg_attr(not(test), no_std)]
