//! Links the bmr core into a `#![no_std]` static library with no global allocator.
#![no_std]

use core::panic::PanicInfo;

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    loop {}
}

pub use bmr as _core_linked;
