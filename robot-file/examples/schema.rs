//! Prints the robot file's JSON schema: `cargo run -p robot-file --example schema > robots/robot.schema.json`.
fn main() {
    print!("{}", robot_file::json_schema());
}
