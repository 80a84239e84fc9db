//! SIGINT, SIGTERM and SIGHUP stop the stream between frames, so that it is marked aborted
//! instead of looking like a killed one.

/// The signal that asked the stream to stop (0: none yet).
pub(super) static STOP_SIGNAL: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(0);

extern "C" fn on_stop_signal(sig: libc::c_int) {
    STOP_SIGNAL.store(sig, std::sync::atomic::Ordering::Relaxed);
}

/// SIGINT, SIGTERM and SIGHUP stop the stream between frames, so it can be marked aborted
/// instead of looking like a killed one; a second signal kills at once (`SA_RESETHAND`).
pub(super) fn catch_signals() {
    // SAFETY: the handler only stores to an atomic (async-signal-safe); the sigaction struct is
    // zeroed (an empty mask, no flags) before the fields set here, and sigaction copies it
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = on_stop_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        sa.sa_flags = libc::SA_RESTART | libc::SA_RESETHAND;
        libc::sigemptyset(&mut sa.sa_mask);
        for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            libc::sigaction(sig, &sa, std::ptr::null_mut());
        }
    }
}

pub(super) fn stop_signal() -> Option<i32> {
    match STOP_SIGNAL.load(std::sync::atomic::Ordering::Relaxed) {
        0 => None,
        s => Some(s),
    }
}

pub(super) fn signal_name(sig: i32) -> String {
    match sig {
        libc::SIGINT => "SIGINT".into(),
        libc::SIGTERM => "SIGTERM".into(),
        libc::SIGHUP => "SIGHUP".into(),
        s => format!("signal {s}"),
    }
}

/// Ends the process by `sig` with its default action, as if it had not been caught, so the
/// parent sees the signal (a shell's 128 + n).
pub(super) fn die_by(sig: i32) -> ! {
    // SAFETY: restoring the default action and raising a signal are plain libc calls on a valid
    // signal number; the default action of SIGINT, SIGTERM and SIGHUP ends the process
    unsafe {
        libc::signal(sig, libc::SIG_DFL);
        libc::raise(sig);
    }
    std::process::exit(128 + sig)
}
