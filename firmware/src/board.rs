//! The board: QEMU's `mps2-an386` (ARM MPS2 FPGA image AN386, Cortex-M4F, 25 MHz).
//!
//! Only what the twin needs, behind the `embedded-hal` 1.0 / `embedded-io` traits the
//! rest of the firmware is written against: UART0 (CMSDK APB UART) for the serial
//! stream and the FPGA I/O LED 0 as the status pin. A real part replaces this module
//! with its HAL's types, which implement the same traits (see README.md).

use core::convert::Infallible;
use core::ptr::{read_volatile, write_volatile};

/// Core and peripheral clock [Hz] of the AN386 image.
pub const SYSCLK_HZ: u32 = 25_000_000;

const UART0_BASE: usize = 0x4000_4000;
const UART_DATA: usize = 0x00;
const UART_STATE: usize = 0x04;
const UART_CTRL: usize = 0x08;
const UART_BAUDDIV: usize = 0x10;
const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;

/// FPGA I/O block: LED register, bits 0..1 drive the user LEDs.
const FPGAIO_LED: usize = 0x4002_8000;

fn reg_read(addr: usize) -> u32 {
    // SAFETY: `addr` is one of the fixed, always-mapped device registers above.
    unsafe { read_volatile(addr as *const u32) }
}

fn reg_write(addr: usize, v: u32) {
    // SAFETY: as in `reg_read`; these registers have no memory-safety side effects.
    unsafe { write_volatile(addr as *mut u32, v) }
}

/// Transmit half of UART0.
pub struct UartTx(());
/// Receive half of UART0.
pub struct UartRx(());

/// Enable UART0 at `baud`; its two halves.
pub fn uart0(baud: u32) -> (UartTx, UartRx) {
    // The CMSDK UART needs a divider of at least 16.
    reg_write(UART0_BASE + UART_BAUDDIV, (SYSCLK_HZ / baud.max(1)).max(16));
    reg_write(UART0_BASE + UART_CTRL, CTRL_TX_EN | CTRL_RX_EN);
    (UartTx(()), UartRx(()))
}

fn uart_state() -> u32 {
    reg_read(UART0_BASE + UART_STATE)
}

impl embedded_io::ErrorType for UartTx {
    type Error = Infallible;
}

impl embedded_io::Write for UartTx {
    /// Blocks until at least one byte is taken (the trait's contract), then takes what
    /// the holding register accepts without waiting.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        let mut n = 0;
        for &b in buf {
            if n > 0 && uart_state() & STATE_TX_FULL != 0 {
                break;
            }
            while uart_state() & STATE_TX_FULL != 0 {}
            reg_write(UART0_BASE + UART_DATA, u32::from(b));
            n += 1;
        }
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        while uart_state() & STATE_TX_FULL != 0 {}
        Ok(())
    }
}

impl embedded_io::WriteReady for UartTx {
    fn write_ready(&mut self) -> Result<bool, Infallible> {
        Ok(uart_state() & STATE_TX_FULL == 0)
    }
}

impl embedded_io::ErrorType for UartRx {
    type Error = Infallible;
}

impl embedded_io::Read for UartRx {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let Some(first) = buf.first_mut() else {
            return Ok(0);
        };
        while uart_state() & STATE_RX_FULL == 0 {}
        *first = reg_read(UART0_BASE + UART_DATA) as u8;
        Ok(1)
    }
}

impl embedded_io::ReadReady for UartRx {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(uart_state() & STATE_RX_FULL != 0)
    }
}

/// The status pin: FPGA I/O user LED 0.
pub struct StatusLed(());

impl StatusLed {
    /// Take the LED, off.
    pub fn new() -> Self {
        let mut led = Self(());
        let _ = embedded_hal::digital::OutputPin::set_low(&mut led);
        led
    }
}

impl Default for StatusLed {
    fn default() -> Self {
        Self::new()
    }
}

impl embedded_hal::digital::ErrorType for StatusLed {
    type Error = Infallible;
}

impl embedded_hal::digital::OutputPin for StatusLed {
    fn set_high(&mut self) -> Result<(), Infallible> {
        reg_write(FPGAIO_LED, reg_read(FPGAIO_LED) | 1);
        Ok(())
    }

    fn set_low(&mut self) -> Result<(), Infallible> {
        reg_write(FPGAIO_LED, reg_read(FPGAIO_LED) & !1);
        Ok(())
    }
}
