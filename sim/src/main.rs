//! `mgmot-sim`: simulated autopilot and maritime frame generator (work in progress).
fn main() {
    println!("mgmot-sim");
}
