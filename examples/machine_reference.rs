//! Prints the machine-speed reference of the face_scan bench (benches/common/reference.rs:
//! the median time of a fixed single-threaded sort), so that scripts outside the benches
//! (scripts/vs_meshlab.py) can print the same figure beside their medians.
//!
//! cargo run --release --example machine_reference

#[path = "../benches/common/reference.rs"]
mod reference;

fn main() {
    println!("{:.1}", reference::reference_workload_ms());
}
