//! The temporary files a signal removes. In a program that asked for it
//! ([`super::output::remove_temporaries_on_signals`]: the `kinecal` command), SIGINT, SIGTERM
//! and SIGHUP remove every live temporary output file and then end the process as the signal
//! would have; a signal that comes while outputs are being renamed into place (a commit) waits
//! until the commit is done, so that a run's outputs are all replaced or none. A signal the
//! process was started ignoring, as under `nohup`, stays ignored.
//!
//! All of it runs in the signal handler, so it does only what is async-signal-safe: each live
//! temporary file's path is a NUL-terminated string in one of [`SLOTS`] atomic slots, which the
//! handler reads and passes to `unlink`; one atomic word ([`Gate`]) counts the commits under
//! way and says when the process is ending, and another keeps the signal a commit defers, raised
//! again when the last commit ends. (A thread waiting on the signals did this
//! before: it cost each run a thread and a malloc arena of its own, 3-4 % of the CPU of a
//! 1,000-pose calibration.) A temporary file beyond the [`SLOTS`] alive at once is not
//! removed by a signal; the next run writing into its folder removes it (see
//! [`super::output`]).

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicUsize, Ordering::SeqCst};

/// The most temporary files a signal removes (alive at once).
const SLOTS: usize = 256;

/// Set in a [`Gate`]'s state once a signal is ending the process: no commit starts after it.
const ENDING: usize = 1 << (usize::BITS - 1);

/// What the signal handler and the commits share: the commits under way (the low bits of
/// `state`) and [`ENDING`]; the signal a commit deferred (`pending`, 0: none).
struct Gate {
    state: AtomicUsize,
    pending: AtomicI32,
}

impl Gate {
    const fn new() -> Gate {
        Gate {
            state: AtomicUsize::new(0),
            pending: AtomicI32::new(0),
        }
    }

    /// Starts a commit: `false` when a signal is ending the process (none may start).
    fn enter(&self) -> bool {
        loop {
            let s = self.state.load(SeqCst);
            if s & ENDING != 0 {
                return false;
            }
            if self
                .state
                .compare_exchange(s, s + 1, SeqCst, SeqCst)
                .is_ok()
            {
                return true;
            }
        }
    }

    /// Ends a commit: the signal to raise again when it was the last one and a signal came
    /// during it.
    fn leave(&self) -> Option<i32> {
        if self.state.fetch_sub(1, SeqCst) != 1 {
            return None;
        }
        Some(self.pending.swap(0, SeqCst)).filter(|&sig| sig != 0)
    }

    /// What the handler does on `sig`: `true` when it is to remove the temporary files and end
    /// the process now (no commit under way; [`ENDING`] is then set), `false` when a commit
    /// defers it (the last one hands it back) or another signal is already ending the process.
    fn take_signal(&self, sig: i32) -> bool {
        // Stored before the state is read: a commit that ends after this reads it and hands it
        // back; one that ended before left the state at 0, and the signal is taken here.
        self.pending.store(sig, SeqCst);
        loop {
            if self.state.load(SeqCst) != 0 {
                return false;
            }
            if self
                .state
                .compare_exchange(0, ENDING, SeqCst, SeqCst)
                .is_ok()
            {
                return true;
            }
        }
    }

    /// Whether a signal is ending the process.
    fn ending(&self) -> bool {
        self.state.load(SeqCst) & ENDING != 0
    }
}

/// The process's gate.
static GATE: Gate = Gate::new();

/// Whether the program asked for temporary files to be removed on signals.
static ASKED: AtomicBool = AtomicBool::new(false);

/// Asks that temporary files be removed on SIGINT, SIGTERM and SIGHUP (the handlers are
/// installed with the first temporary file).
pub(crate) fn ask() {
    ASKED.store(true, SeqCst);
}

/// A temporary file known to the signal handler (when the program asked for it and a slot was
/// free): its slot is emptied when this is dropped. Drop it after the file is removed or
/// renamed, so that a signal in between finds the path gone rather than the file left.
pub(crate) struct Registered(Option<usize>);

/// Makes the temporary file at `path` known to the signal handler.
pub(crate) fn register(path: &Path) -> Registered {
    if !ASKED.load(SeqCst) {
        return Registered(None);
    }
    imp::register(path)
}

impl Drop for Registered {
    fn drop(&mut self) {
        if let Some(slot) = self.0.take() {
            imp::unregister(slot);
        }
    }
}

/// A commit under way: while one lives, a signal waits (it is raised again when the last one is
/// dropped). Waits forever when a signal is already ending the process.
pub(crate) struct Committing(());

/// Starts a commit.
pub(crate) fn committing() -> Committing {
    if !GATE.enter() {
        // The handler is removing the temporary files and ending the process: nothing may be
        // renamed now.
        imp::wait_for_the_end();
    }
    Committing(())
}

impl Drop for Committing {
    fn drop(&mut self) {
        if let Some(sig) = GATE.leave() {
            imp::raise(sig);
        }
    }
}

#[cfg(unix)]
mod imp {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt as _;
    use std::path::Path;
    use std::ptr;
    use std::sync::atomic::{AtomicPtr, Ordering::SeqCst};

    use super::{Registered, GATE, SLOTS};

    /// The live temporary files' paths (null: a free slot), each a `CString` of its own.
    static PATHS: [AtomicPtr<libc::c_char>; SLOTS] =
        [const { AtomicPtr::new(ptr::null_mut()) }; SLOTS];

    pub(super) fn register(path: &Path) -> Registered {
        install();
        let Ok(c) = CString::new(path.as_os_str().as_bytes()) else {
            return Registered(None);
        };
        let p = c.into_raw();
        for (slot, at) in PATHS.iter().enumerate() {
            if at
                .compare_exchange(ptr::null_mut(), p, SeqCst, SeqCst)
                .is_ok()
            {
                return Registered(Some(slot));
            }
        }
        // SAFETY: `p` came from `into_raw` above and was stored nowhere.
        drop(unsafe { CString::from_raw(p) });
        Registered(None)
    }

    pub(super) fn unregister(slot: usize) {
        let p = PATHS[slot].swap(ptr::null_mut(), SeqCst);
        // A handler that read the slot before the swap set `ENDING` before reading it, so it
        // is seen here: the string is then kept for it (the process is ending).
        if !p.is_null() && !GATE.ending() {
            // SAFETY: `p` came from `into_raw` in `register`, and no handler can read it now:
            // the slot is empty, and none began before the swap (`ENDING` is not set).
            drop(unsafe { CString::from_raw(p) });
        }
    }

    pub(super) fn raise(sig: i32) {
        let _ = signal_hook::low_level::raise(sig);
    }

    pub(super) fn wait_for_the_end() -> ! {
        loop {
            // SAFETY: pause only suspends this thread until a signal arrives.
            unsafe { libc::pause() };
        }
    }

    /// Installs the handler of SIGINT, SIGTERM and SIGHUP, once, leaving alone a signal the
    /// process was started ignoring.
    fn install() {
        static ONCE: std::sync::Once = std::sync::Once::new();
        ONCE.call_once(|| {
            use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
            for sig in [SIGINT, SIGTERM, SIGHUP] {
                if ignored(sig) {
                    continue;
                }
                // SAFETY: the action is async-signal-safe: atomics, `unlink`, and
                // signal-hook's emulation of the default action (documented as such).
                let _ = unsafe { signal_hook::low_level::register(sig, move || handle(sig)) };
            }
        });
    }

    /// The handler: the temporary files removed and the process ended as `sig` would have,
    /// unless a commit defers it.
    fn handle(sig: i32) {
        if !GATE.take_signal(sig) {
            return;
        }
        for at in &PATHS {
            let p = at.load(SeqCst);
            if !p.is_null() {
                // SAFETY: a NUL-terminated path, not freed while `ENDING` is set.
                unsafe { libc::unlink(p) };
            }
        }
        let _ = signal_hook::low_level::emulate_default_handler(sig);
        signal_hook::low_level::exit(128 + sig);
    }

    /// Whether the process was started with `sig` ignored (`nohup`, a background job).
    fn ignored(sig: i32) -> bool {
        // SAFETY: reads the current action only (a null new action changes nothing).
        unsafe {
            let mut old: libc::sigaction = std::mem::zeroed();
            libc::sigaction(sig, std::ptr::null(), &mut old) == 0
                && old.sa_sigaction == libc::SIG_IGN
        }
    }
}

#[cfg(not(unix))]
mod imp {
    use std::path::Path;

    use super::Registered;

    pub(super) fn register(_: &Path) -> Registered {
        Registered(None)
    }

    pub(super) fn unregister(_: usize) {}

    pub(super) fn raise(_: i32) {}

    pub(super) fn wait_for_the_end() -> ! {
        loop {
            std::thread::park();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The handler's decisions against the commits (on a gate of the test's own): a signal
    /// during commits is deferred and handed back by the last one to end; with no commit, it
    /// ends the process, no commit starts after that, and a second signal is left to the first.
    #[test]
    fn a_signal_waits_for_the_commits() {
        let gate = Gate::new();
        assert!(gate.enter() && gate.enter());
        assert!(!gate.take_signal(15), "taken during two commits");
        assert_eq!(
            gate.leave(),
            None,
            "handed back before the last commit ended"
        );
        assert_eq!(gate.leave(), Some(15), "not handed back by the last commit");
        assert!(gate.enter());
        assert_eq!(gate.leave(), None, "handed back twice");
        assert!(gate.take_signal(2), "no commit under way, yet deferred");
        assert!(gate.ending());
        assert!(
            !gate.enter(),
            "a commit started while a signal ends the process"
        );
        assert!(
            !gate.take_signal(1),
            "a second signal taken while the first ends the process"
        );
    }

    /// A signal that comes as the last commit ends is taken once: by the handler (the commit
    /// ended first) or handed back by the commit (the handler read the state first).
    #[test]
    fn a_signal_as_the_last_commit_ends_is_taken_once() {
        for handler_first in [false, true] {
            let gate = Gate::new();
            assert!(gate.enter());
            let (taken, handed_back) = if handler_first {
                let taken = gate.take_signal(15);
                (taken, gate.leave())
            } else {
                let handed_back = gate.leave();
                (gate.take_signal(15), handed_back)
            };
            assert_eq!(
                u8::from(taken) + u8::from(handed_back.is_some()),
                1,
                "handler first: {handler_first}"
            );
        }
    }
}
