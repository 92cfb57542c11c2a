//! The save that fills a page and moves the record to the next one (once
//! per page-full of records, with an erase) reads the flash a bounded
//! number of times over: linear in the store's size, not quadratic in the
//! items the page holds. Uncached, sequential-storage's map searched the
//! page for the newest item of every item it migrated: on the firmware's
//! 128 KiB pages that save ran past the 8.2 s stretched watchdog on the
//! emulated STM32F446 (stm32-emu check (m)), so it never completed (D105).
//! Counted in bytes read (deterministic), not timed.

use embedded_storage_async::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use robot_store::{validate_robot, RamFlash, RobotStore};
use std::cell::Cell;

const PAGE: usize = 128 * 1024;
const SIZE: usize = 2 * PAGE;

/// RamFlash counting the bytes read and the pages erased.
struct Counting<'a> {
    inner: Box<RamFlash<SIZE, PAGE>>,
    read_bytes: &'a Cell<u64>,
    erases: &'a Cell<u32>,
}

impl ErrorType for Counting<'_> {
    type Error = robot_store::RamFlashError;
}

impl ReadNorFlash for Counting<'_> {
    const READ_SIZE: usize = 1;
    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.read_bytes
            .set(self.read_bytes.get() + bytes.len() as u64);
        self.inner.read(offset, bytes).await
    }
    fn capacity(&self) -> usize {
        SIZE
    }
}

impl NorFlash for Counting<'_> {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = PAGE;
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.erases.set(self.erases.get() + 1);
        self.inner.erase(from, to).await
    }
    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.inner.write(offset, bytes).await
    }
}

#[test]
fn the_page_moving_save_reads_the_store_a_bounded_number_of_times() {
    let mut blob = [0u8; robot_file::MAX_ENCODED_LEN];
    let n = robot_file::Robot::paper().encode(&mut blob).unwrap();
    let (read_bytes, erases) = (Cell::new(0u64), Cell::new(0u32));
    let flash = Counting {
        inner: Box::new(RamFlash::new()),
        read_bytes: &read_bytes,
        erases: &erases,
    };
    // One store for the whole run, as the firmware keeps one from boot.
    let mut store = RobotStore::new(flash, 0..SIZE as u32).unwrap();
    let mut worst_normal = 0u64;
    for saves in 0..5_000u32 {
        let (reads_before, erases_before) = (read_bytes.get(), erases.get());
        embassy_futures::block_on(store.save(validate_robot, &blob[..n])).unwrap();
        let read = read_bytes.get() - reads_before;
        if erases.get() > erases_before {
            eprintln!(
                "save {saves} moved the record to the next page with an erase: {read} B read \
                 (a normal save at most {worst_normal} B; the store is {SIZE} B)"
            );
            assert!(saves > 100, "a page held only {saves} records");
            // Linear: a few passes over the store (item headers and the
            // live record), whatever the number of items in the page.
            assert!(
                read <= 4 * SIZE as u64,
                "the page-moving save read {read} B, more than 4 passes over the {SIZE} B store"
            );
            return;
        }
        worst_normal = worst_normal.max(read);
    }
    panic!("no page move in 5000 saves");
}
