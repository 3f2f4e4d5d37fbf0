//! The worker pool's threads, each pinned to a CPU of its own when asked
//! (`MICROCAM_PIN_THREADS=1`).
//!
//! Why this exists: on some virtual machines the guest scheduler packs
//! runnable threads onto fewer virtual CPUs to spare the host (a kernel
//! that treats a halted vCPU as busy, or a packing policy such as the
//! `sched_vcpu_pack` of the machine our benchmarks run on). There a rayon
//! worker woken for a parallel step is queued behind the thread that woke
//! it while the other CPU idles, often for the 4 ms until the next load
//! balance; `perf sched timehist` showed such waits of 3 to 7 ms in the
//! parallel stages of a 0.2 s `dxf2chains` run. Pinning each worker to its
//! own CPU makes every wake-up land on that CPU.
//!
//! Off by default, because it is a trade: on that machine, idle, a DXF
//! import took 0.91x-1.02x the time pinned (about 0.95x) and two threads
//! cast 10-25 % more rays a second; with one CPU taken by another
//! process, pinned imports took 1.06x-1.20x the time (a pinned worker
//! cannot move off the busy CPU). Pinning only when the machine looks idle
//! at start was tried: the kernel's count of runnable threads at that
//! instant caught the tool's own launcher (a shell, a pipeline's other
//! tools starting) in two of three idle starts, so the choice would be a
//! coin toss. docs/dxf.md ("where the idle time goes") has the runs and the
//! commands.

/// The environment variable that asks for pinned workers: any value but
/// empty or `0`.
pub const PIN_ENV: &str = "MICROCAM_PIN_THREADS";

/// Whether the environment asks for pinned workers.
pub fn pinning_asked() -> bool {
    asks(std::env::var_os(PIN_ENV).as_deref())
}

/// Whether a value of [`PIN_ENV`] asks for pinning.
fn asks(value: Option<&std::ffi::OsStr>) -> bool {
    value.is_some_and(|v| !v.is_empty() && v != "0")
}

/// Build rayon's global pool with pinned workers when the environment asks
/// for it; otherwise do nothing (rayon builds its pool on first use).
/// Called once, before any parallel work. The pool keeps rayon's own
/// choice of size (`RAYON_NUM_THREADS`, or one worker per CPU); worker `i`
/// is pinned to the `i`-th CPU this process may run on, round robin when
/// there are more workers than CPUs.
pub fn init_pool() {
    if !pinning_asked() {
        return;
    }
    if let Some(builder) = pinned_builder() {
        // A pool already built (a second call, or a library user's own) is
        // kept as it is: pinning is a speed hint, never a failure.
        let _ = builder.build_global();
    }
}

/// A pool builder whose workers pin themselves, one CPU each; `None` where
/// the CPUs this process may use cannot be read (or off Linux), or there is
/// only one.
pub fn pinned_builder() -> Option<rayon::ThreadPoolBuilder> {
    let cpus = allowed_cpus()?;
    if cpus.len() < 2 {
        return None;
    }
    Some(rayon::ThreadPoolBuilder::new().start_handler(move |i| pin_current_thread(cpus[i % cpus.len()])))
}

/// The CPUs the calling thread may run on, in increasing order.
#[cfg(target_os = "linux")]
pub fn allowed_cpus() -> Option<Vec<usize>> {
    // SAFETY: `set` is a plain bit set, zeroed, of the size passed; the
    // kernel writes at most that many bytes into it.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return None;
        }
        Some(
            (0..libc::CPU_SETSIZE as usize)
                .filter(|&c| libc::CPU_ISSET(c, &set))
                .collect(),
        )
    }
}

/// The CPUs the calling thread may run on (unknown off Linux).
#[cfg(not(target_os = "linux"))]
pub fn allowed_cpus() -> Option<Vec<usize>> {
    None
}

/// Pin the calling thread to `cpu`; a refusal (the CPU went offline, a
/// cgroup changed) leaves the thread where the scheduler puts it.
#[cfg(target_os = "linux")]
fn pin_current_thread(cpu: usize) {
    // SAFETY: as in `allowed_cpus`; `cpu` is below CPU_SETSIZE, as every
    // CPU `sched_getaffinity` reported is.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        let _ = libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
    }
}

#[cfg(not(target_os = "linux"))]
fn pin_current_thread(_cpu: usize) {}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    #[test]
    fn each_worker_of_a_pinned_pool_runs_on_one_allowed_cpu_of_its_own() {
        let cpus = allowed_cpus().expect("sched_getaffinity works on Linux");
        assert!(!cpus.is_empty());
        if cpus.len() < 2 {
            assert!(pinned_builder().is_none(), "one CPU: nothing to pin");
            return;
        }
        let n = cpus.len().min(4);
        let pool = pinned_builder().unwrap().num_threads(n).build().unwrap();
        let mut seen: Vec<(usize, Vec<usize>)> = pool.broadcast(|ctx| (ctx.index(), allowed_cpus().unwrap()));
        seen.sort();
        for (i, mine) in &seen {
            assert_eq!(
                mine,
                &vec![cpus[*i]],
                "worker {i} is pinned to the {i}-th allowed CPU alone"
            );
        }
        // The test's own thread is not a worker: it keeps every CPU.
        assert_eq!(allowed_cpus().unwrap(), cpus);
    }

    #[test]
    fn more_workers_than_cpus_go_round_robin() {
        let cpus = allowed_cpus().unwrap();
        if cpus.len() < 2 {
            return; // nothing is pinned (checked above)
        }
        let n = cpus.len() + 1;
        let pool = pinned_builder().unwrap().num_threads(n).build().unwrap();
        let mut seen: Vec<(usize, Vec<usize>)> = pool.broadcast(|ctx| (ctx.index(), allowed_cpus().unwrap()));
        seen.sort();
        assert_eq!(seen.len(), n);
        assert_eq!(seen[n - 1].1, vec![cpus[0]]);
    }

    #[test]
    fn only_a_nonempty_value_other_than_zero_asks() {
        // The value, not the process environment (other tests run beside).
        let v = |s: &'static str| Some(std::ffi::OsStr::new(s));
        assert!(asks(v("1")));
        assert!(asks(v("yes")));
        assert!(!asks(v("0")));
        assert!(!asks(v("")));
        assert!(!asks(None));
    }
}
