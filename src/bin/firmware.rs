//! Firmware placeholder (issue 3 builds the RTIC app here).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the firmware runs on the STM32F407: build it with `cargo fw`");
}
