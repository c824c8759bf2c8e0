//! The long hostile-input run: seeded cases (tests/common/hostile.rs) through the reference, the
//! parallel backend and the GPU (when there is an adapter), each checked for panics, agreement
//! between the backends and the report's invariants.
//!
//! ```sh
//! cargo run --release --example fuzz -- --cases 1000000 [--seed 0] [--cpu-only]
//! ```
//!
//! Prints a tally every 50k cases and at the end (cases, reports, errors by variant, cases on
//! the GPU, failures with their seeds); exits with 1 if a case failed, and with 2 if one case
//! runs for over a minute (a hang), naming its seed. A failing seed reruns alone with
//! `--seed S --cases 1`; add it to `FOUND` in tests/fuzz.rs to keep it as a regression.

#[path = "../tests/common/hostile.rs"]
mod hostile;

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use hostile::{Backends, check, generate};
use voxcollide::GpuContext;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str, default: u64| -> u64 {
        match args.iter().position(|a| a == flag) {
            Some(i) => match args.get(i + 1).and_then(|v| v.parse().ok()) {
                Some(v) => v,
                None => {
                    eprintln!("error: {flag} needs a whole number");
                    std::process::exit(64);
                }
            },
            None => default,
        }
    };
    let cases = value("--cases", 1_000_000);
    let first = value("--seed", 0);
    let cpu_only = args.iter().any(|a| a == "--cpu-only");
    let gpu = if cpu_only {
        None
    } else {
        match GpuContext::new() {
            Ok(ctx) => Some(ctx),
            Err(e) => {
                eprintln!("no GPU adapter ({e}); running the CPU backends only");
                None
            }
        }
    };
    let adapter = gpu.as_ref().map_or_else(|| "none".to_string(), GpuContext::adapter_name);
    let backends = Backends::new(gpu);
    println!(
        "{cases} cases from seed {first}; GPU: {adapter} (forces compared bit for bit: {})",
        backends.gpu_exact
    );

    // The watchdog: a case that runs for over a minute is a hang.
    let current = Arc::new(AtomicU64::new(u64::MAX));
    let started = Arc::new(AtomicU64::new(0));
    let clock = Instant::now();
    {
        let (current, started) = (current.clone(), started.clone());
        std::thread::spawn(move || {
            loop {
                std::thread::sleep(Duration::from_secs(5));
                let seed = current.load(Ordering::SeqCst);
                let since = clock.elapsed().as_secs().saturating_sub(started.load(Ordering::SeqCst));
                if seed != u64::MAX && since > 60 {
                    eprintln!("HANG: seed {seed} has run for {since} s");
                    std::process::exit(2);
                }
            }
        });
    }

    let mut tally = Tally::default();
    for seed in first..first.saturating_add(cases) {
        started.store(clock.elapsed().as_secs(), Ordering::SeqCst);
        current.store(seed, Ordering::SeqCst);
        tally.add(seed, check(&generate(seed), &backends));
        let done = seed - first + 1;
        if done % 50_000 == 0 && done < cases {
            println!("{done} cases, {:.0} s: {}", clock.elapsed().as_secs_f64(), tally.line());
        }
    }
    current.store(u64::MAX, Ordering::SeqCst);
    println!("{cases} cases in {:.0} s: {}", clock.elapsed().as_secs_f64(), tally.line());
    for f in &tally.failures {
        println!("FAILED {f}");
    }
    std::process::exit(i32::from(!tally.failures.is_empty()));
}

#[derive(Default)]
struct Tally {
    reports: u64,
    with_contacts: u64,
    on_gpu: u64,
    errors: BTreeMap<String, u64>,
    panics: u64,
    failures: Vec<String>,
}

impl Tally {
    fn add(&mut self, seed: u64, result: Result<hostile::Outcome, String>) {
        match result {
            Ok(o) => {
                self.on_gpu += u64::from(o.gpu_ran);
                if o.result == "ok" {
                    self.reports += 1;
                    self.with_contacts += u64::from(o.contacts > 0);
                } else {
                    *self.errors.entry(o.result).or_default() += 1;
                }
            }
            Err(e) => {
                self.panics += u64::from(e.contains("panicked"));
                if self.failures.len() < 100 {
                    self.failures.push(format!("seed {seed}: {e}"));
                }
                eprintln!("FAILED seed {seed}: {e}");
            }
        }
    }

    fn line(&self) -> String {
        format!(
            "{} reports ({} with contacts), {} on the GPU, errors {:?}, {} panics, {} failures",
            self.reports,
            self.with_contacts,
            self.on_gpu,
            self.errors,
            self.panics,
            self.failures.len()
        )
    }
}
