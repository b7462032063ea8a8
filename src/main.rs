fn main() {
    eprintln!("scanmill: command line arrives with the I/O merge");
}
