//! The device interrupt vectors (cortex-m-rt's `device` feature): the MPS2 AN386 (and QEMU's
//! model of it) has 32 external interrupts, so the table has 32 entries instead of the 240 that
//! cortex-m-rt reserves without a device crate (832 bytes of flash saved). The firmware enables
//! none of them (its timer is SysTick, an exception): every entry is the default handler. A
//! board build links its PAC instead, which provides the board's own table.

/// One vector table entry (the layout PACs use).
#[repr(C)]
pub union Vector {
    handler: unsafe extern "C" fn(),
    reserved: usize,
}

extern "C" {
    /// cortex-m-rt's default handler (`DefaultHandler_` unless the application defines one).
    fn DefaultHandler();
}

/// External interrupts of the MPS2 AN386 (CMSDK Cortex-M4 subsystem, QEMU `num-irq` 32).
pub const DEVICE_INTERRUPTS: usize = 32;

const DEFAULT: Vector = Vector { handler: DefaultHandler };

/// The device part of the vector table, placed after the exceptions by cortex-m-rt's link.x.
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
#[used]
pub static __INTERRUPTS: [Vector; DEVICE_INTERRUPTS] = [DEFAULT; DEVICE_INTERRUPTS];
