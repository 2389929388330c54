fn main() {
    std::process::exit(robopost::cli::main());
}
