//! Prints `Robot::paper()` as a robot file, and its derived values.
fn main() {
    let r = robot_file::Robot::paper();
    r.validate().expect("the paper robot is valid");
    print!("{}", r.to_toml_string());
}
