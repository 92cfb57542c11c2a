//! The store and validator with robot-file's real binary form: the example
//! robots round-trip through flash; a robot with a field out of range or
//! NaN is refused naming that field; a corrupted record is refused by its
//! CRC-32.

use embassy_futures::block_on;
use robot_file::Robot;
use robot_store::{validate_robot, LoadFault, RamFlash, RobotStore, StoreError, ROBOT_BLOB_MAX};
use wmr_protocol::RobotFaultKind;

type Ram = RamFlash<4096, 1024>;

fn example(name: &str) -> Robot {
    let path = format!("{}/../robots/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    Robot::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn encode(r: &Robot) -> Vec<u8> {
    let mut buf = [0u8; ROBOT_BLOB_MAX];
    let n = r.encode(&mut buf).unwrap();
    buf[..n].to_vec()
}

#[test]
fn the_example_robots_round_trip_through_flash() {
    let mut store = RobotStore::new(Ram::new(), 0..4096).unwrap();
    for name in ["paper", "tb6612-2kg", "bts7960-10kg"] {
        let blob = encode(&example(name));
        assert_eq!(
            block_on(store.save(validate_robot, &blob)),
            Ok(()),
            "{name}"
        );
        let mut out = [0u8; ROBOT_BLOB_MAX];
        let n = block_on(store.load(validate_robot, &mut out)).unwrap();
        assert_eq!(&out[..n], blob.as_slice());
        assert_eq!(Robot::decode(&out[..n]).unwrap(), example(name));
    }
}

#[test]
fn a_field_out_of_range_or_nan_is_refused_naming_the_field() {
    let mut r = example("tb6612-2kg");
    r.body.wheel_radius_m[1] = 7.0;
    let fault = validate_robot(&encode(&r)).unwrap_err();
    assert_eq!(fault.kind, RobotFaultKind::OutOfRange);
    assert_eq!(fault.field.as_str(), "body.wheel_radius_m[1]");
    let [lo, hi] = fault.range.unwrap();
    assert!(lo < 0.035 && 0.035 < hi && hi < 7.0, "[{lo}, {hi}]");

    let mut r = example("tb6612-2kg");
    r.body.mass_kg = f32::NAN;
    let fault = validate_robot(&encode(&r)).unwrap_err();
    assert_eq!(fault.kind, RobotFaultKind::NotFinite);
    assert_eq!(fault.field.as_str(), "body.mass_kg");

    // Refused by the store too: nothing written.
    let mut store = RobotStore::new(Ram::new(), 0..4096).unwrap();
    let e = block_on(store.save(validate_robot, &encode(&r))).unwrap_err();
    assert!(matches!(e, StoreError::Invalid(_)), "{e:?}");
    let mut out = [0u8; ROBOT_BLOB_MAX];
    assert_eq!(
        block_on(store.load(validate_robot, &mut out)),
        Err(LoadFault::Missing)
    );
}

#[test]
fn a_corrupted_record_is_refused_by_its_crc() {
    let mut blob = encode(&example("paper"));
    let mid = blob.len() / 2;
    blob[mid] ^= 0x01;
    let fault = validate_robot(&blob).unwrap_err();
    assert_eq!(fault.kind, RobotFaultKind::BadCrc);
    assert!(fault.field.is_empty());
    assert_eq!(
        validate_robot(&blob[..10]).unwrap_err().kind,
        RobotFaultKind::Truncated
    );
}
