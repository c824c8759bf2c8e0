//! The live view's simulation, stepped on its own thread (issue 21, item 6): the window draws
//! the latest state it has published while it goes on stepping, so that drawing and stepping
//! share the machine's cores instead of taking turns within a frame.
//!
//! In real time the thread steps as many times as the wall clock has advanced since it last
//! looked, in batches of at most [`BATCH`] seconds of stepping, and publishes the world after
//! each batch. What it cannot pay in a batch is dropped, not carried, and the run is then
//! *behind*: a slow machine runs slower than real time instead of ever further behind. With
//! a fixed number of steps a frame (`--steps-per-frame`, repeatable runs), it steps only when a
//! frame asks, and the frame waits for those steps: the same frames as stepping in the frame.

use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use voxcollide::{ContactReport, Error};
use voxcollide_sim::World;

use super::controls::Pacing;
use crate::scene_run::Run;

/// The longest the thread steps before it publishes what it has (seconds).
pub const BATCH: f64 = 0.02;

/// A state of the run, as the thread published it.
#[derive(Clone, Debug)]
pub struct Snapshot {
    /// The bodies.
    pub world: World,
    /// The last step's contact reports.
    pub reports: Vec<ContactReport>,
    /// Steps since the start or the last reset.
    pub steps: u64,
    /// Simulated seconds since the start or the last reset.
    pub time: f64,
}

/// What the window and the thread share.
struct Shared {
    paused: bool,
    /// Steps asked for while paused.
    step_once: u64,
    /// Fixed steps a frame: the steps the frames have asked for so far, and done so far.
    fixed: bool,
    asked: u64,
    done: u64,
    /// A new run to step from now on (a reset).
    reset: Option<Run>,
    quit: bool,
    /// The latest state, until the window takes it.
    latest: Option<Snapshot>,
    /// Steps over the whole view, resets included.
    steps_total: u64,
    /// Why the run stopped, until a reset.
    broken: Option<Error>,
    /// Whether the last batch fell behind real time.
    behind: bool,
    /// In real time, the least wall time between published states (0: after every batch).
    snapshot_every: f64,
    /// States read from the run and published (on the GPU backend, each a read-back).
    snapshots: u64,
    /// Whether the thread is waiting while paused, with no step under way.
    idle_paused: bool,
}

/// The stepping thread and what it shares with the window.
pub struct Stepper {
    shared: Arc<(Mutex<Shared>, Condvar)>,
    thread: Option<JoinHandle<()>>,
}

fn lock(shared: &(Mutex<Shared>, Condvar)) -> MutexGuard<'_, Shared> {
    shared.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl Stepper {
    /// Starts stepping `run` (steps of `dt` seconds) in real time, or only as frames ask when
    /// `fixed`. Its first state is published at once.
    ///
    /// # Errors
    /// [`Error::Invalid`] when the thread cannot be started.
    pub fn start(mut run: Run, dt: f64, fixed: bool) -> Result<Stepper, Error> {
        let first = snapshot(&mut run, 0, dt as f32).ok();
        let snapshots = u64::from(first.is_some());
        let shared = Arc::new((
            Mutex::new(Shared {
                paused: false,
                step_once: 0,
                fixed,
                asked: 0,
                done: 0,
                reset: None,
                quit: false,
                latest: first,
                steps_total: 0,
                broken: None,
                behind: false,
                snapshot_every: 0.0,
                snapshots,
                idle_paused: false,
            }),
            Condvar::new(),
        ));
        let theirs = Arc::clone(&shared);
        let thread = std::thread::Builder::new()
            .name("voxcollide-step".into())
            .spawn(move || step_loop(run, dt, &theirs))
            .map_err(|e| Error::Invalid {
                what: "view",
                value: e.to_string(),
                rule: "needs a thread to step on".into(),
            })?;
        Ok(Stepper { shared, thread: Some(thread) })
    }

    /// Pauses or resumes the stepping.
    pub fn set_paused(&self, paused: bool) {
        lock(&self.shared).paused = paused;
        self.shared.1.notify_all();
    }

    /// Waits until the thread has seen the pause: the batch under way when it was asked for
    /// has ended, and nothing steps until [`step_once`](Self::step_once) or a resume. (The
    /// window needs no such wait: it draws whatever was published.)
    #[cfg(test)]
    pub fn wait_paused(&self) {
        let until = Instant::now() + Duration::from_secs(20);
        let mut s = lock(&self.shared);
        while s.paused && !s.idle_paused && s.broken.is_none() && !s.quit && Instant::now() < until {
            s = self
                .shared
                .1
                .wait_timeout(s, Duration::from_millis(100))
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .0;
        }
    }

    /// One step while paused.
    pub fn step_once(&self) {
        lock(&self.shared).step_once += 1;
        self.shared.1.notify_all();
    }

    /// Steps from `run` on, from its start.
    pub fn reset(&self, run: Run) {
        let mut s = lock(&self.shared);
        s.reset = Some(run);
        s.broken = None;
        s.latest = None;
        drop(s);
        self.shared.1.notify_all();
    }

    /// Fixed steps a frame: asks for `n` steps and waits until they are done (or the run
    /// stops).
    pub fn step_and_wait(&self, n: u64) {
        let mut s = lock(&self.shared);
        s.asked += n;
        self.shared.1.notify_all();
        while s.done < s.asked && s.broken.is_none() && !s.quit {
            s = self.shared.1.wait(s).unwrap_or_else(std::sync::PoisonError::into_inner);
        }
    }

    /// In real time, publishes the run's state at most every `seconds` of wall time instead of
    /// after every batch: while the window draws the bodies from their positions on the device,
    /// a state serves only the heads-up numbers, and on the GPU backend each is a read-back.
    /// Fixed steps a frame publish after every batch regardless (a repeatable run).
    pub fn set_snapshot_every(&self, seconds: f64) {
        lock(&self.shared).snapshot_every = seconds;
    }

    /// States published so far (on the GPU backend, each read back from the device).
    pub fn snapshots(&self) -> u64 {
        lock(&self.shared).snapshots
    }

    /// The state published since the last call, if any.
    pub fn take_latest(&self) -> Option<Snapshot> {
        lock(&self.shared).latest.take()
    }

    /// Steps over the whole view, whether the last batch fell behind real time, and why the
    /// run stopped (if it did).
    pub fn status(&self) -> (u64, bool, Option<Error>) {
        let s = lock(&self.shared);
        (s.steps_total, s.behind, s.broken.clone())
    }
}

impl Drop for Stepper {
    fn drop(&mut self) {
        lock(&self.shared).quit = true;
        self.shared.1.notify_all();
        if let Some(thread) = self.thread.take() {
            thread.join().ok();
        }
    }
}

/// The run's state now.
fn snapshot(run: &mut Run, steps: u64, dt: f32) -> Result<Snapshot, Error> {
    let time = crate::scene_run::simulated_time(&**run, steps, dt);
    let (world, reports) = run.frame()?;
    Ok(Snapshot { world: world.clone(), reports, steps, time })
}

fn step_loop(mut run: Run, dt: f64, shared: &(Mutex<Shared>, Condvar)) {
    let mut pacing = Pacing::new(dt, BATCH);
    let mut steps = 0u64;
    let mut last = Instant::now();
    let mut published = Instant::now();
    // Steps done since the state was last published.
    let mut owed = false;
    loop {
        // What to do now, decided under the lock; and whether to publish the state after it.
        let (n, every) = {
            let mut s = lock(shared);
            if s.quit {
                return;
            }
            if let Some(fresh) = s.reset.take() {
                run = fresh;
                steps = 0;
                pacing.owed = 0.0;
                s.latest = snapshot(&mut run, 0, dt as f32).ok();
                s.snapshots += u64::from(s.latest.is_some());
                published = Instant::now();
                owed = false;
            }
            let now = Instant::now();
            let elapsed = now.duration_since(last).as_secs_f64();
            last = now;
            let n = if s.broken.is_some() {
                0
            } else if s.fixed {
                s.asked - s.done
            } else if s.paused {
                pacing.owed = 0.0;
                std::mem::take(&mut s.step_once)
            } else {
                let (n, behind) = pacing.steps(elapsed);
                s.behind = behind;
                n
            };
            if n == 0 && owed && s.broken.is_none() && (s.paused || s.fixed) {
                // Nothing to step until the user or a frame asks: the state a throttled
                // publishing held back, now (in real time the next batch is due soon).
                (0, 0.0)
            } else if n == 0 {
                s.idle_paused = s.paused;
                shared.1.notify_all();
                // Until a frame asks, or a step is owed.
                let wait = if s.fixed || s.paused || s.broken.is_some() {
                    Duration::from_millis(50)
                } else {
                    Duration::from_secs_f64((dt - pacing.owed).clamp(0.0005, 0.005))
                };
                drop(shared.1.wait_timeout(s, wait).unwrap_or_else(std::sync::PoisonError::into_inner));
                continue;
            } else {
                s.idle_paused = false;
                (n, if s.fixed || s.paused { 0.0 } else { s.snapshot_every })
            }
        };
        let t = Instant::now();
        let mut stepped = 0;
        let mut broken = None;
        for _ in 0..n {
            if let Err(e) = run.step() {
                broken = Some(e);
                break;
            }
            stepped += 1;
        }
        steps += stepped;
        owed |= stepped > 0;
        if n > 0 {
            pacing.took(stepped, t.elapsed().as_secs_f64());
        }
        // A stopped run is not read again: on the GPU the read-back is where a blow-up shows.
        let due = published.elapsed().as_secs_f64() >= every;
        let shot = match broken {
            Some(_) => None,
            None if !due => None,
            None => match snapshot(&mut run, steps, dt as f32) {
                Ok(s) => Some(s),
                Err(e) => {
                    broken = Some(e);
                    None
                }
            },
        };
        let mut s = lock(shared);
        s.steps_total += stepped;
        if s.fixed {
            s.done += n;
        }
        if s.reset.is_none() {
            if let Some(shot) = shot {
                s.latest = Some(shot);
                s.snapshots += 1;
                published = Instant::now();
                owed = false;
            }
            if broken.is_some() {
                s.broken = broken;
            }
        }
        drop(s);
        shared.1.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use voxcollide_sim::build::build_world;
    use voxcollide_sim::scene_file::SceneFile;
    use voxcollide_sim::simulation;

    const BLOCK: &str = "units = \"mm\"\n[time]\nduration = 10.0\n[[body]]\nname = \"block\"\nkind = \"soft\"\nshape = { box = [20, 20, 10] }\nspacing = 2.5\nmaterial = { young_kpa = 3.0, density = 1000.0, damping = 0.5 }\nfixed = [{ below = { z = -4.9 } }]\n";

    fn block(fixed: bool) -> Stepper {
        let built = build_world(&SceneFile::parse("block.toml", BLOCK).unwrap()).unwrap();
        Stepper::start(simulation(None, built.world).unwrap(), f64::from(built.dt), fixed).unwrap()
    }

    fn wait_for(stepper: &Stepper, what: impl Fn(u64) -> bool) -> u64 {
        let until = Instant::now() + Duration::from_secs(20);
        loop {
            let (steps, _, broken) = stepper.status();
            assert!(broken.is_none(), "{broken:?}");
            if what(steps) || Instant::now() > until {
                return steps;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    #[test]
    fn in_real_time_it_steps_without_frames_and_pause_and_single_steps_hold() {
        let s = block(false);
        assert_eq!(s.take_latest().map(|l| l.steps), Some(0), "the first state is there at once");
        // No frame asks: it steps on its own.
        let steps = wait_for(&s, |n| n >= 20);
        assert!(steps >= 20, "only {steps} steps in 20 s");
        let latest = wait_for(&s, |_| true);
        assert!(s.take_latest().is_some_and(|l| l.steps > 0 && l.time > 0.0), "{latest}");
        s.set_paused(true);
        // The batch under way ends (however long a loaded machine makes it); then nothing moves.
        s.wait_paused();
        let (paused_at, _, _) = s.status();
        std::thread::sleep(Duration::from_millis(200));
        assert_eq!(s.status().0, paused_at, "stepped while paused");
        s.step_once();
        assert_eq!(wait_for(&s, |n| n > paused_at), paused_at + 1, "one step asked for");
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(s.status().0, paused_at + 1, "more than the one step");
    }

    #[test]
    fn fixed_steps_a_frame_are_done_before_the_frame_goes_on_and_a_reset_starts_over() {
        let s = block(true);
        s.take_latest();
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(s.status().0, 0, "a repeatable run steps only when a frame asks");
        s.step_and_wait(7);
        assert_eq!(s.status().0, 7);
        assert_eq!(s.take_latest().map(|l| l.steps), Some(7));
        s.step_and_wait(3);
        assert_eq!(s.take_latest().map(|l| l.steps), Some(10));
        let built = build_world(&SceneFile::parse("block.toml", BLOCK).unwrap()).unwrap();
        s.reset(simulation(None, built.world).unwrap());
        s.step_and_wait(2);
        let latest = s.take_latest().expect("a state after the reset");
        assert_eq!(latest.steps, 2, "counted from the reset");
        assert_eq!(s.status().0, 12, "the whole view's steps go on");
    }
}
