//! The job queue in front of the one engine.
//!
//! Jobs wait in a bounded queue; `workers` tasks take them one at a time (one for a GPU engine;
//! configurable for the CPU engine). Scheduling policy: the queued job with the lowest
//! `estimated cost − age credit` runs next, where the cost is its voxel count (plus triangles)
//! and every second of waiting earns the credit of a 256³ job. Small jobs therefore overtake a
//! huge one, but a huge one that has waited long enough runs before newer small ones: nothing
//! waits forever. A full queue refuses new jobs (429) and never drops accepted ones.
//!
//! Cancelling a queued job removes it; cancelling a running one marks it canceled and its result
//! is discarded when the engine returns (engines are not interruptible mid-kernel).

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

use serde::{Deserialize, Serialize};
use tokio::sync::{Mutex, Notify, watch};

use super::problem::Problem;
use crate::engine::Method;
use crate::grid::Grid;
use crate::mesh::{Mesh, MeshDiagnostics};

/// Voxel credit per second of waiting (a 256³ job).
const AGE_CREDIT_PER_SEC: f64 = 256.0 * 256.0 * 256.0;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum State {
    Queued,
    Running,
    Succeeded,
    Failed,
    Canceled,
}

impl State {
    pub fn is_final(self) -> bool {
        matches!(self, State::Succeeded | State::Failed | State::Canceled)
    }
    pub fn name(self) -> &'static str {
        match self {
            State::Queued => "queued",
            State::Running => "running",
            State::Succeeded => "succeeded",
            State::Failed => "failed",
            State::Canceled => "canceled",
        }
    }
}

/// A bit method, or density with its sub-voxel factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MethodSpec {
    Bits(Method),
    Density(u32),
}

impl MethodSpec {
    pub fn name(self) -> &'static str {
        match self {
            MethodSpec::Bits(m) => m.name(),
            MethodSpec::Density(_) => "density",
        }
    }
}

/// What a job computes.
pub struct Work {
    pub mesh: Mesh,
    pub diagnostics: MeshDiagnostics,
    pub grid: Grid,
    pub method: MethodSpec,
    pub fill: crate::engine::fill::Fill,
    pub name: Option<String>,
    pub format: String,
    pub sha256: String,
}

/// The job as the API shows it (and as it is stored in `jobs/{id}.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobView {
    pub id: String,
    pub state: State,
    /// 1-based position in the queue while queued.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub position: Option<usize>,
    pub progress: f64,
    pub method: String,
    pub grid: Grid,
    pub name: Option<String>,
    pub created: String,
    pub timings: Timings,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_id: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub problem: Option<Problem>,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Timings {
    /// Seconds spent queued, running, and in total (so far, while unfinished).
    pub queued_s: Option<f64>,
    pub running_s: Option<f64>,
}

struct Job {
    view: JobView,
    /// A record of an earlier process: shown as stored.
    loaded: bool,
    work: Option<Arc<Work>>,
    cost: f64,
    enqueued: Instant,
    started: Option<Instant>,
    finished: Option<Instant>,
    canceled: Arc<AtomicBool>,
    done: watch::Sender<State>,
}

pub struct Jobs {
    inner: Mutex<Inner>,
    ready: Notify,
    capacity: usize,
    /// Where job records are kept (`data_dir/jobs`); none in memory-only use.
    dir: Option<std::path::PathBuf>,
}

struct Inner {
    jobs: HashMap<String, Job>,
    /// Ids of queued jobs, in arrival order.
    queue: Vec<String>,
    closed: bool,
}

/// Why a job was not accepted.
pub enum Refused {
    Full { capacity: usize },
    Closed,
}

impl Jobs {
    /// A queue whose job records live in `dir`. Records of earlier runs are loaded; a job that
    /// was queued or running when that process died is marked failed (interrupted), since its
    /// mesh was only in memory.
    pub fn open(capacity: usize, dir: std::path::PathBuf) -> std::io::Result<Jobs> {
        std::fs::create_dir_all(&dir)?;
        let mut jobs = HashMap::new();
        for entry in std::fs::read_dir(&dir)? {
            let p = entry?.path();
            if p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with('.'))
            {
                let _ = std::fs::remove_file(&p);
                continue;
            }
            let Some(mut view) = std::fs::read(&p)
                .ok()
                .and_then(|b| serde_json::from_slice::<JobView>(&b).ok())
            else {
                tracing::warn!(path = %p.display(), "ignoring unreadable job record");
                continue;
            };
            if !view.state.is_final() {
                view.state = State::Failed;
                view.position = None;
                view.problem = Some(Problem::new(
                    super::problem::Kind::ShuttingDown,
                    "interrupted: the server stopped before this job finished; submit it again",
                ));
                persist(&dir, &view);
            }
            let (done, _) = watch::channel(view.state);
            let now = Instant::now();
            let canceled = Arc::new(AtomicBool::new(false));
            jobs.insert(
                view.id.clone(),
                Job {
                    view,
                    loaded: true,
                    work: None,
                    cost: 0.0,
                    enqueued: now,
                    started: None,
                    finished: Some(now),
                    canceled,
                    done,
                },
            );
        }
        tracing::info!(jobs = jobs.len(), "job records loaded");
        Ok(Jobs {
            inner: Mutex::new(Inner {
                jobs,
                queue: vec![],
                closed: false,
            }),
            ready: Notify::new(),
            capacity,
            dir: Some(dir),
        })
    }

    fn persist(&self, view: &JobView) {
        if let Some(dir) = &self.dir {
            persist(dir, view);
        }
    }

    /// Queues a job; its id and a receiver that sees its state.
    pub async fn submit(
        &self,
        id: String,
        work: Work,
        created: String,
    ) -> Result<(JobView, watch::Receiver<State>), Refused> {
        let mut inner = self.inner.lock().await;
        if inner.closed {
            return Err(Refused::Closed);
        }
        if inner.queue.len() >= self.capacity {
            return Err(Refused::Full {
                capacity: self.capacity,
            });
        }
        let fine = match work.method {
            MethodSpec::Density(f) => (f * f * f) as f64,
            MethodSpec::Bits(_) => 1.0,
        };
        let cost =
            fine * work.grid.voxel_count() as f64 + 64.0 * work.mesh.triangles().len() as f64;
        let (tx, rx) = watch::channel(State::Queued);
        let view = JobView {
            id: id.clone(),
            state: State::Queued,
            position: None,
            progress: 0.0,
            method: work.method.name().into(),
            grid: work.grid,
            name: work.name.clone(),
            created,
            timings: Timings::default(),
            volume_id: None,
            problem: None,
        };
        inner.jobs.insert(
            id.clone(),
            Job {
                view,
                loaded: false,
                work: Some(Arc::new(work)),
                cost,
                enqueued: Instant::now(),
                started: None,
                finished: None,
                canceled: Arc::new(AtomicBool::new(false)),
                done: tx,
            },
        );
        inner.queue.push(id.clone());
        let v = inner.view(&id).expect("just inserted");
        self.persist(&v);
        drop(inner);
        self.ready.notify_one();
        Ok((v, rx))
    }

    pub async fn view(&self, id: &str) -> Option<JobView> {
        self.inner.lock().await.view(id)
    }

    pub async fn watch(&self, id: &str) -> Option<watch::Receiver<State>> {
        self.inner
            .lock()
            .await
            .jobs
            .get(id)
            .map(|j| j.done.subscribe())
    }

    /// Cancels a queued or running job. `Err(state)` when it had already finished.
    pub async fn cancel(&self, id: &str) -> Option<Result<JobView, State>> {
        let mut inner = self.inner.lock().await;
        let job = inner.jobs.get_mut(id)?;
        if job.view.state.is_final() {
            return Some(Err(job.view.state));
        }
        job.canceled.store(true, Ordering::SeqCst);
        job.view.state = State::Canceled;
        job.finished = Some(Instant::now());
        job.work = None;
        let _ = job.done.send(State::Canceled);
        inner.queue.retain(|q| q != id);
        let v = inner.view(id).expect("present");
        self.persist(&v);
        Some(Ok(v))
    }

    pub async fn depth(&self) -> usize {
        self.inner.lock().await.queue.len()
    }

    pub async fn count_by_state(&self) -> HashMap<(State, String), u64> {
        let inner = self.inner.lock().await;
        let mut m = HashMap::new();
        for j in inner.jobs.values() {
            *m.entry((j.view.state, j.view.method.clone())).or_insert(0) += 1;
        }
        m
    }

    /// Waits for the next job by the scheduling policy; `None` once closed and drained.
    pub async fn next(&self) -> Option<(String, Arc<Work>, Arc<AtomicBool>)> {
        loop {
            {
                let mut inner = self.inner.lock().await;
                let now = Instant::now();
                let pick = inner
                    .queue
                    .iter()
                    .enumerate()
                    .min_by(|(_, a), (_, b)| {
                        let score = |id: &String| {
                            let j = &inner.jobs[id];
                            j.cost
                                - AGE_CREDIT_PER_SEC * now.duration_since(j.enqueued).as_secs_f64()
                        };
                        score(a).total_cmp(&score(b))
                    })
                    .map(|(i, _)| i);
                if let Some(i) = pick {
                    let id = inner.queue.remove(i);
                    let job = inner.jobs.get_mut(&id).expect("queued job exists");
                    job.view.state = State::Running;
                    job.started = Some(now);
                    let _ = job.done.send(State::Running);
                    return Some((
                        id,
                        job.work.clone().expect("queued work"),
                        job.canceled.clone(),
                    ));
                }
                if inner.closed {
                    return None;
                }
            }
            self.ready.notified().await;
        }
    }

    /// Records the end of a running job.
    pub async fn finish(&self, id: &str, result: Result<String, Problem>) {
        let mut inner = self.inner.lock().await;
        let Some(job) = inner.jobs.get_mut(id) else {
            return;
        };
        job.work = None;
        if job.view.state == State::Canceled {
            return;
        }
        job.finished = Some(Instant::now());
        match result {
            Ok(volume) => {
                job.view.state = State::Succeeded;
                job.view.volume_id = Some(volume);
                job.view.progress = 1.0;
            }
            Err(p) => {
                job.view.state = State::Failed;
                job.view.problem = Some(p);
            }
        }
        let _ = job.done.send(job.view.state);
        let v = inner.view(id).expect("present");
        self.persist(&v);
    }

    /// Stops accepting jobs and fails every queued one explicitly (for shutdown); running jobs
    /// finish.
    pub async fn close(&self, why: Problem) -> usize {
        let mut inner = self.inner.lock().await;
        inner.closed = true;
        let queued: Vec<String> = std::mem::take(&mut inner.queue);
        for id in &queued {
            if let Some(job) = inner.jobs.get_mut(id) {
                job.view.state = State::Failed;
                job.view.problem = Some(why.clone());
                job.work = None;
                job.finished = Some(Instant::now());
                let _ = job.done.send(State::Failed);
            }
            if let Some(v) = inner.view(id) {
                self.persist(&v);
            }
        }
        drop(inner);
        self.ready.notify_waiters();
        queued.len()
    }

    pub async fn running(&self) -> usize {
        self.inner
            .lock()
            .await
            .jobs
            .values()
            .filter(|j| j.view.state == State::Running)
            .count()
    }
}

impl Inner {
    fn view(&self, id: &str) -> Option<JobView> {
        let j = self.jobs.get(id)?;
        if j.loaded {
            return Some(j.view.clone());
        }
        let mut v = j.view.clone();
        v.position = (v.state == State::Queued)
            .then(|| self.queue.iter().position(|q| q == id).map(|p| p + 1))
            .flatten();
        let now = Instant::now();
        let secs = |d: Duration| (d.as_secs_f64() * 1000.0).round() / 1000.0;
        v.timings.queued_s = Some(secs(
            j.started
                .unwrap_or(j.finished.unwrap_or(now))
                .duration_since(j.enqueued),
        ));
        v.timings.running_s = j
            .started
            .map(|s| secs(j.finished.unwrap_or(now).duration_since(s)));
        Some(v)
    }
}

fn persist(dir: &std::path::Path, view: &JobView) {
    let bytes = serde_json::to_vec(view).expect("job record serialises");
    if let Err(e) = super::store::write_atomic(dir, &format!("{}.json", view.id), &bytes) {
        tracing::error!(job = %view.id, "cannot write the job record: {e}");
    }
}

/// RFC 3339 UTC time of `t` (seconds precision).
pub fn rfc3339(t: SystemTime) -> String {
    let secs = t
        .duration_since(SystemTime::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0) as i64;
    let (days, rem) = (secs.div_euclid(86400), secs.rem_euclid(86400));
    // Civil from days (Howard Hinnant).
    let z = days + 719468;
    let era = z.div_euclid(146097);
    let doe = z - era * 146097;
    let yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rfc3339_dates() {
        assert_eq!(rfc3339(SystemTime::UNIX_EPOCH), "1970-01-01T00:00:00Z");
        assert_eq!(
            rfc3339(SystemTime::UNIX_EPOCH + Duration::from_secs(1_795_000_000)),
            "2026-11-18T11:06:40Z"
        );
        assert_eq!(
            rfc3339(SystemTime::UNIX_EPOCH + Duration::from_secs(951_782_400)),
            "2000-02-29T00:00:00Z"
        );
    }
}
