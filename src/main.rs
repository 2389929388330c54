//! The `robopost` command: the process's setup (signals, allocator, logging) around the
//! library's command line.

fn main() {
    // Rust ignores SIGPIPE, so a closed pipe (`robopost ik … | head`) makes println! panic.
    // A command-line filter should instead end quietly, as cat or grep do.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of one signal before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    keep_freed_memory();
    trace_if_asked();
    robopost::exit_with_command_line(std::env::args().collect());
}

/// With `ROBOPOST_LOG` set (a `tracing` filter such as `robopost=info`, or `robopost=trace` for
/// every window of a streamed program): the time of each phase of the main job on standard
/// error, as each span closes. Unset, no subscriber exists and the spans cost a check each.
fn trace_if_asked() {
    let Some(value) = std::env::var_os("ROBOPOST_LOG") else {
        return;
    };
    let filter = match tracing_subscriber::EnvFilter::try_from_env("ROBOPOST_LOG") {
        Ok(filter) => filter,
        Err(e) => {
            eprintln!(
                "warning: ROBOPOST_LOG={value:?} is not a tracing filter ({e}); no timings printed"
            );
            return;
        }
    };
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_span_events(tracing_subscriber::fmt::format::FmtSpan::CLOSE)
        .with_writer(std::io::stderr)
        .init();
}

/// glibc's allocator hands blocks over 128 KiB back to the kernel when they are freed (and
/// trims the top of its heaps), moving that limit up as it sees such blocks freed. A batch
/// allocates and frees a few such blocks per program a thousand times over; where the limit
/// lags behind, every one comes back as fresh pages, faulted in one by one (330,000 faults
/// for a batch of 1,000 programs, a quarter of its time). Fixed limits keep freed memory for
/// reuse; blocks of 32 MiB and more (a long program's bytes) are still mapped on their own.
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only sets allocator parameters; called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}
