//! Power loss and wear of the robot record.
//!
//! * A power cut at every byte operation (erase or write) of a save,
//!   through a sequence of saves that wraps the pages (so cuts also land in
//!   page migrations and erases), with two independent fault models:
//!   sequential-storage's own mock flash (`bytes_until_shutoff`) and this
//!   crate's [`RamFlash`] (`cut_after`). After each cut, a fresh store (a
//!   reboot) loads exactly the old record or the new one, never anything
//!   else; and the next save succeeds (the store repairs itself).
//! * Wear: many saves spread the erases evenly over the pages, and a page
//!   is erased once per page-full of records, not once per record.
//! * Fallback: missing, wrong-format and invalid records are reported as
//!   such, never returned.

use embassy_futures::block_on;
use embedded_storage_async::nor_flash::NorFlash;
use robot_store::{
    LoadFault, RamFlash, RobotFault, RobotStore, StoreError, RECORD_FORMAT, RECORD_KEY,
    ROBOT_BLOB_MAX,
};
use sequential_storage::mock_flash::{MockFlashBase, WriteCountCheck};
use wmr_protocol::RobotFaultKind;

/// 4 pages of 1 KiB, 4-byte words.
type Mock = MockFlashBase<4, 4, 256>;
type Ram = RamFlash<4096, 1024>;
const RANGE: core::ops::Range<u32> = 0..4096;

/// A test blob: `[len_lo, len_hi, payload..., sum32 (LE)]`, where sum32 is
/// a simple checksum of everything before it (an independent stand-in for
/// robot-file's CRC-32; robot-file's own codec is exercised in hil-sim's
/// device test).
fn blob(seed: u8, len: usize) -> Vec<u8> {
    let mut b = vec![0u8; len];
    b[0] = (len & 0xFF) as u8;
    b[1] = (len >> 8) as u8;
    for (i, x) in b[2..len - 4].iter_mut().enumerate() {
        *x = seed.wrapping_mul(31).wrapping_add(i as u8);
    }
    let s = sum32(&b[..len - 4]);
    b[len - 4..].copy_from_slice(&s.to_le_bytes());
    b
}

fn sum32(b: &[u8]) -> u32 {
    b.iter().fold(0x811C_9DC5u32, |h, &x| {
        (h ^ x as u32).wrapping_mul(0x0100_0193)
    })
}

fn validate(b: &[u8]) -> Result<(), RobotFault> {
    let bad = |k| Err(RobotFault::new(k, "", None));
    if b.len() < 6 {
        return bad(RobotFaultKind::Truncated);
    }
    if (b[0] as usize | (b[1] as usize) << 8) != b.len() {
        return bad(RobotFaultKind::BadLength);
    }
    let n = b.len() - 4;
    if sum32(&b[..n]).to_le_bytes() != b[n..] {
        return bad(RobotFaultKind::BadCrc);
    }
    Ok(())
}

fn accept_all(_: &[u8]) -> Result<(), RobotFault> {
    Ok(())
}

fn load<F: NorFlash>(flash: F) -> (Result<Vec<u8>, LoadFault>, F) {
    let mut store = RobotStore::new(flash, RANGE).unwrap();
    let mut out = [0u8; ROBOT_BLOB_MAX];
    let r = block_on(store.load(validate, &mut out)).map(|n| out[..n].to_vec());
    (r, store.into_flash())
}

fn save<F: NorFlash>(flash: F, b: &[u8]) -> (Result<(), StoreError>, F) {
    let mut store = RobotStore::new(flash, RANGE).unwrap();
    let r = block_on(store.save(validate, b));
    (r, store.into_flash())
}

/// Saves 30 records of 60 to 460 bytes (about 3 per page: the 4 pages
/// wrap at least twice, so saves migrate and erase pages), cutting the power at every byte operation of each
/// save; returns how many cuts were tried.
fn cut_everywhere<F: NorFlash + Clone>(
    fresh: F,
    set_cut: fn(&mut F, Option<u32>),
) -> (usize, usize) {
    let mut erasing_saves = 0;
    let mut base = fresh;
    let mut old: Option<Vec<u8>> = None;
    let (mut cuts, mut old_seen) = (0, 0);
    for k in 0..30u8 {
        let new = blob(k, 60 + (k as usize * 137) % 400);
        for cut in 0u32.. {
            let mut f = base.clone();
            set_cut(&mut f, Some(cut));
            let (r, mut f) = save(f, &new);
            set_cut(&mut f, None);
            let (loaded, f) = load(f);
            if r.is_ok() {
                erasing_saves += usize::from(cut > 1024);
                // The whole save ran before the cut.
                assert_eq!(loaded.as_ref(), Ok(&new), "save {k} completed, not loaded");
                base = f;
                break;
            }
            cuts += 1;
            match (&loaded, &old) {
                (Ok(b), _) if *b == new => {}
                (Ok(b), Some(o)) if b == o => old_seen += 1,
                (Err(LoadFault::Missing), None) => old_seen += 1,
                _ => panic!("save {k}, cut at byte {cut}: loaded {loaded:?}"),
            }
            // The interrupted store repairs itself: the next save works.
            let (r2, f) = save(f, &new);
            assert_eq!(r2, Ok(()), "save {k} after a cut at {cut}");
            assert_eq!(load(f).0.as_ref(), Ok(&new));
        }
        old = Some(new);
    }
    // Cuts landed inside page erases too.
    assert!(erasing_saves >= 2, "{erasing_saves} saves erased a page");
    (cuts, old_seen)
}

#[test]
fn power_cut_at_every_byte_of_a_save_leaves_old_or_new_in_the_mock_flash() {
    let fresh = Mock::new(WriteCountCheck::Twice, None, true);
    let (cuts, old_seen) = cut_everywhere(fresh, |f, c| f.bytes_until_shutoff = c);
    eprintln!("mock flash: {cuts} power cuts, old record kept after {old_seen}");
    // Most cuts land before the item is complete: the old record stays.
    assert!(cuts > 30 * 60 + 2 * 1024, "only {cuts} cut points");
    assert!(
        old_seen > cuts / 2,
        "old record after {old_seen} of {cuts} cuts"
    );
}

#[test]
fn power_cut_at_every_byte_of_a_save_leaves_old_or_new_in_ram_flash() {
    let (cuts, old_seen) = cut_everywhere(Ram::new(), |f, c| f.cut_after = c);
    eprintln!("RamFlash: {cuts} power cuts, old record kept after {old_seen}");
    assert!(cuts > 30 * 60 + 2 * 1024, "only {cuts} cut points");
    assert!(
        old_seen > cuts / 2,
        "old record after {old_seen} of {cuts} cuts"
    );
}

#[test]
fn erases_spread_evenly_over_the_pages() {
    let saves = 1000;
    let len = 200;
    let mut f = Ram::new();
    for k in 0..saves {
        let (r, g) = save(f, &blob(k as u8, len));
        assert_eq!(r, Ok(()));
        f = g;
    }
    let erases = f.erases().to_vec();
    let total: u32 = erases.iter().sum();
    let (lo, hi) = (*erases.iter().min().unwrap(), *erases.iter().max().unwrap());
    // Cyclic use: no page erased more than once more than another.
    assert!(hi - lo <= 1, "erases per page {erases:?}");
    // An item is the value (1 + len bytes) plus its header and padding
    // (under 32 bytes): at least 1024 / (len + 1 + 32) = 4 per page, so
    // at most one erase per 4 saves (+ the pages' first use).
    eprintln!("{saves} saves of {len} B: erases per page {erases:?}");
    let per_page = 1024 / (len + 1 + 32);
    assert!(
        total as usize <= saves / per_page + 4,
        "{total} erases for {saves} saves"
    );
    // And the record is still the last one.
    assert_eq!(load(f).0, Ok(blob((saves - 1) as u8, len)));
}

#[test]
fn missing_record_is_reported_missing() {
    let (r, _) = load(Ram::new());
    assert_eq!(r, Err(LoadFault::Missing));
    assert_eq!(
        LoadFault::Missing.source(),
        wmr_protocol::RobotSource::DefaultMissing
    );
}

#[test]
fn invalid_blob_is_refused_and_nothing_is_written() {
    let mut bad = blob(1, 100);
    bad[50] ^= 1;
    let (r, f) = save(Ram::new(), &bad);
    assert!(matches!(r, Err(StoreError::Invalid(_))), "{r:?}");
    assert_eq!(f.erases().iter().sum::<u32>(), 0);
    assert_eq!(load(f).0, Err(LoadFault::Missing));
    let (r, _) = save(Ram::new(), &[]);
    assert_eq!(r, Err(StoreError::Length));
    let (r, _) = save(Ram::new(), &[0u8; ROBOT_BLOB_MAX + 1]);
    assert_eq!(r, Err(StoreError::Length));
}

#[test]
fn a_stored_record_that_no_longer_validates_is_reported_corrupt() {
    // Stored by a build whose validator accepted it (e.g. another robot
    // format), read by one whose validator does not.
    let mut bad = blob(2, 100);
    bad[60] ^= 0x10;
    let mut store = RobotStore::new(Ram::new(), RANGE).unwrap();
    assert_eq!(block_on(store.save(accept_all, &bad)), Ok(()));
    let (r, _) = load(store.into_flash());
    match r {
        Err(e @ LoadFault::Invalid(_)) => {
            assert_eq!(e.source(), wmr_protocol::RobotSource::DefaultCorrupt)
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_record_of_another_layout_version_is_reported_corrupt() {
    let mut store = RobotStore::new(Ram::new(), RANGE).unwrap();
    assert_eq!(block_on(store.save(validate, &blob(3, 80))), Ok(()));
    let mut f = store.into_flash();
    // Rewrite the record with another format byte through the map itself
    // (so its item CRC is right and only the layout version differs).
    let mut map = sequential_storage::map::MapStorage::<u8, _, _>::new(
        &mut f,
        sequential_storage::map::MapConfig::new(RANGE),
        sequential_storage::cache::Cache::new_uncached(),
    );
    let mut v = vec![RECORD_FORMAT + 1];
    v.extend(blob(3, 80));
    let mut buf = [0u8; 640];
    block_on(map.store_item(&mut buf, &RECORD_KEY, &v.as_slice())).unwrap();
    let _ = map.destroy();
    let (r, _) = load(f);
    assert_eq!(r, Err(LoadFault::Format));
}

#[test]
fn bit_rot_in_the_only_record_never_returns_garbage() {
    for i in (0..400).step_by(3) {
        let mut store = RobotStore::new(Ram::new(), RANGE).unwrap();
        assert_eq!(block_on(store.save(validate, &blob(4, 120))), Ok(()));
        let mut f = store.into_flash();
        f.bytes_mut()[i] ^= 0x04;
        if let Ok(b) = load(f).0 {
            assert_eq!(b, blob(4, 120), "flip at {i}");
        }
    }
}
