//! Prints `Robot::paper()` as a robot file and the length of its binary form.
fn main() {
    let r = robot_file::Robot::paper();
    r.validate().expect("the paper robot is valid");
    print!("{}", r.to_toml_string());
    let mut buf = [0u8; robot_file::MAX_ENCODED_LEN];
    let n = r.encode(&mut buf).expect("fits");
    eprintln!("binary form: {n} bytes");
    let mut full = r.clone();
    for k in controller_core::ControllerKind::ALL {
        let g = Some(robot_file::GainSet::paper(k));
        match k {
            controller_core::ControllerKind::Proposed => full.gains.proposed = g,
            controller_core::ControllerKind::Smc => full.gains.smc = g,
            controller_core::ControllerKind::Asmc => full.gains.asmc = g,
        }
    }
    let n = full.encode(&mut buf).expect("fits");
    eprintln!("with every gain section: {n} bytes");
}
