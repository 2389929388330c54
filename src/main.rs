fn main() {
    // Rust ignores SIGPIPE, so a closed pipe (`robopost ik … | head`) makes println! panic.
    // A command-line filter should instead end quietly, as cat or grep do.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of one signal before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    std::process::exit(robopost::cli::main());
}
