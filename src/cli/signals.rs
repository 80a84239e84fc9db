//! Stop signals of the long-running commands (`psns stream`, `psns gige`): SIGINT, SIGTERM (and
//! for a stream SIGHUP) are caught and recorded, and the command ends between frames by its own
//! rules; a second signal kills at once (`SA_RESETHAND`), so a run that cannot stop promptly
//! (a trajectory read from a silent stdin) still ends on the next Ctrl-C.

use std::sync::atomic::{AtomicI32, Ordering};

/// The signal that asked the command to stop (0: none yet).
static STOP_SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_stop_signal(sig: libc::c_int) {
    STOP_SIGNAL.store(sig, Ordering::SeqCst);
}

/// Catches `signals`: the first of them is recorded ([`stop_signal`]) and the next one has its
/// default action.
pub fn catch(signals: &[libc::c_int]) {
    // SAFETY: the handler only stores to an atomic (async-signal-safe); the sigaction struct is
    // zeroed (an empty mask, no flags) before the fields set here, and sigaction copies it
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = on_stop_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        sa.sa_flags = libc::SA_RESTART | libc::SA_RESETHAND;
        libc::sigemptyset(&mut sa.sa_mask);
        for &sig in signals {
            libc::sigaction(sig, &sa, std::ptr::null_mut());
        }
    }
}

/// The signal caught, if any.
pub fn stop_signal() -> Option<i32> {
    match STOP_SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// `SIGINT`, `SIGTERM`, `SIGHUP` or `signal N`.
pub fn signal_name(sig: i32) -> String {
    match sig {
        libc::SIGINT => "SIGINT".into(),
        libc::SIGTERM => "SIGTERM".into(),
        libc::SIGHUP => "SIGHUP".into(),
        s => format!("signal {s}"),
    }
}

/// Ends the process by `sig` with its default action, as if it had not been caught, so the
/// parent sees the signal (a shell's 128 + n).
pub fn die_by(sig: i32) -> ! {
    // SAFETY: restoring the default action and raising a signal are plain libc calls on a valid
    // signal number; the default action of SIGINT, SIGTERM and SIGHUP ends the process
    unsafe {
        libc::signal(sig, libc::SIG_DFL);
        libc::raise(sig);
    }
    std::process::exit(128 + sig)
}
