//! Many runs (variants × seeds) on worker threads.
//!
//! Every job builds its own plant, sensors and controller and resets its
//! thread's estimator with the job's seed, so a job's result does not depend
//! on which thread ran it or in which order: the output is identical for any
//! thread count.

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::SimError;
use crate::estimator::RoadEstimator;
use crate::setup::SimSetup;
use crate::sim::{RunResult, Sim};
use crate::variant::Variant;

/// One run of a batch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Job {
    /// Which variant.
    pub variant: Variant,
    /// Run seed.
    pub seed: u64,
    /// Keep the time series.
    pub keep_trace: bool,
}

impl Job {
    /// Every variant for every seed in `seeds`, seed-major; traces kept
    /// for the first seed only unless `all_traces`.
    pub fn grid(variants: &[Variant], seeds: &[u64], all_traces: bool) -> Vec<Job> {
        let mut jobs = Vec::with_capacity(variants.len() * seeds.len());
        for (i, &seed) in seeds.iter().enumerate() {
            for &variant in variants {
                jobs.push(Job {
                    variant,
                    seed,
                    keep_trace: all_traces || i == 0,
                });
            }
        }
        jobs
    }
}

/// Run `jobs` on `threads` worker threads (at least 1). `make_estimator`
/// builds one estimator per thread (wrap it in [`crate::InLoopProbe`] to get
/// [`RunResult::inloop`]); `on_done` is called after each job (for a
/// progress bar; from the worker threads). Results come back in job order;
/// the first error (of `make_estimator` or of a run's setup) stops the batch.
pub fn run_batch(
    setup: &SimSetup,
    jobs: &[Job],
    threads: usize,
    make_estimator: &(dyn Fn() -> Result<Box<dyn RoadEstimator>, SimError> + Sync),
    on_done: &(dyn Fn(&RunResult) + Sync),
) -> Result<Vec<RunResult>, SimError> {
    run_batch_with(&|_| setup, jobs, threads, make_estimator, on_done)
}

/// [`run_batch`] with a setup per job: `setup_of(job)` gives the setup a job
/// runs on (e.g. one scenario per seed, `grip sim --scenario random`). The
/// setups must share the catalogue and the run length that the estimators of
/// `make_estimator` were built for; otherwise as [`run_batch`].
pub fn run_batch_with<'s>(
    setup_of: &(dyn Fn(&Job) -> &'s SimSetup + Sync),
    jobs: &[Job],
    threads: usize,
    make_estimator: &(dyn Fn() -> Result<Box<dyn RoadEstimator>, SimError> + Sync),
    on_done: &(dyn Fn(&RunResult) + Sync),
) -> Result<Vec<RunResult>, SimError> {
    let threads = threads.clamp(1, jobs.len().max(1));
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Result<RunResult, SimError>>>> =
        Mutex::new((0..jobs.len()).map(|_| None).collect());
    let worker = || {
        let mut est = match make_estimator() {
            Ok(e) => e,
            Err(e) => {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i < jobs.len()
                    && let Ok(mut g) = results.lock()
                {
                    g[i] = Some(Err(e));
                }
                next.store(jobs.len(), Ordering::Relaxed);
                return;
            }
        };
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            let Some(job) = jobs.get(i) else { break };
            let r = Sim::new(
                setup_of(job),
                job.variant,
                job.seed,
                est.as_mut(),
                job.keep_trace,
            )
            .map(Sim::finish);
            if let Ok(r) = &r {
                on_done(r);
            }
            let failed = r.is_err();
            if let Ok(mut g) = results.lock() {
                g[i] = Some(r);
            }
            if failed {
                // Stop handing out work: the setup is bad for every job.
                next.store(jobs.len(), Ordering::Relaxed);
                break;
            }
        }
    };
    if threads == 1 {
        worker();
    } else {
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(worker);
            }
        });
    }
    let results = results
        .into_inner()
        .map_err(|_| SimError::invalid("batch", "a worker thread panicked"))?;
    if let Some(Some(Err(e))) = results.iter().find(|r| matches!(r, Some(Err(_)))) {
        return Err(e.clone());
    }
    let mut out = Vec::with_capacity(jobs.len());
    for r in results {
        match r {
            Some(Ok(r)) => out.push(r),
            Some(Err(e)) => return Err(e),
            None => {
                return Err(SimError::invalid(
                    "batch",
                    "a job did not run (an earlier job failed or a worker panicked)",
                ));
            }
        }
    }
    Ok(out)
}
