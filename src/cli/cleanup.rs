//! Hidden temporary files removed when the process is interrupted.
//!
//! An [`super::Output`] to a file is written into a temporary file beside
//! it. Dropping it removes the file, but SIGINT, SIGTERM or SIGHUP end the
//! process without running destructors, which left 37–158 MB hidden files
//! beside a large output. So every such temporary file is registered here
//! while it exists, and the first registration installs a handler for those
//! signals (only where the signal still has its default action: a tool that
//! installs its own handler, as pmac-send does for its safety stop, keeps
//! it, and then leaves by its own exit path, where destructors run). The
//! handler unlinks every registered path and re-raises the signal with its
//! default action, so the exit status still says which signal ended the
//! run. It touches only lock-free slots holding C strings, and calls only
//! `unlink`, `signal` and `raise`, which are async-signal-safe.

use std::ffi::CString;
use std::path::Path;
use std::sync::Once;
use std::sync::atomic::{AtomicPtr, Ordering};

/// Registered paths at once (a run writes a handful of outputs; a
/// registration beyond this many is simply not cleaned on a signal).
const SLOTS: usize = 256;

static PATHS: [AtomicPtr<libc::c_char>; SLOTS] = [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];
static INSTALL: Once = Once::new();
const SIGNALS: [libc::c_int; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

extern "C" fn on_signal(sig: libc::c_int) {
    for slot in &PATHS {
        let p = slot.swap(std::ptr::null_mut(), Ordering::SeqCst);
        if !p.is_null() {
            // SAFETY: a registered pointer is a leaked, never freed CString.
            unsafe { libc::unlink(p) };
        }
    }
    // SAFETY: restoring the default action and re-raising is the
    // documented way to end on a signal from its handler.
    unsafe {
        libc::signal(sig, libc::SIG_DFL);
        libc::raise(sig);
    }
}

fn install() {
    for sig in SIGNALS {
        // SAFETY: sigaction with a null new action only reads the current
        // one; the handler installed is async-signal-safe (module doc).
        unsafe {
            let mut old: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(sig, std::ptr::null(), &mut old) != 0 || old.sa_sigaction != libc::SIG_DFL {
                continue;
            }
            let mut new: libc::sigaction = std::mem::zeroed();
            new.sa_sigaction = on_signal as *const () as libc::sighandler_t;
            libc::sigemptyset(&mut new.sa_mask);
            libc::sigaction(sig, &new, std::ptr::null_mut());
        }
    }
}

/// A temporary file registered for removal on a signal; dropping the guard
/// unregisters it (the file itself is renamed or removed by its owner).
#[derive(Debug)]
pub struct Guard {
    slot: Option<(usize, *mut libc::c_char)>,
}

// SAFETY: the guard only holds the address of a leaked C string and the
// index of the slot that holds it.
unsafe impl Send for Guard {}
unsafe impl Sync for Guard {}

/// Register `path` (a temporary file this process just created).
pub fn register(path: &Path) -> Guard {
    use std::os::unix::ffi::OsStrExt;
    INSTALL.call_once(install);
    let Ok(c) = CString::new(path.as_os_str().as_bytes()) else {
        return Guard { slot: None };
    };
    // Leaked on purpose: the signal handler may read it at any moment, so
    // it is never freed (a few bytes per output file of a run).
    let p = c.into_raw();
    for (i, slot) in PATHS.iter().enumerate() {
        if slot
            .compare_exchange(std::ptr::null_mut(), p, Ordering::SeqCst, Ordering::SeqCst)
            .is_ok()
        {
            return Guard { slot: Some((i, p)) };
        }
    }
    Guard { slot: None }
}

impl Drop for Guard {
    fn drop(&mut self) {
        if let Some((i, p)) = self.slot.take() {
            let _ = PATHS[i].compare_exchange(p, std::ptr::null_mut(), Ordering::SeqCst, Ordering::SeqCst);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registration_fills_and_frees_a_slot() {
        let g = register(&std::env::temp_dir().join("microcam-cleanup-test"));
        let (i, p) = g.slot.expect("a free slot");
        assert_eq!(PATHS[i].load(Ordering::SeqCst), p);
        drop(g);
        assert_ne!(PATHS[i].load(Ordering::SeqCst), p);
    }
}
