//! The queue's Lua scripts (the `.lua` files beside this one, each run atomically by Redis) and
//! typed calls of them. Every change of a job's state is one script, so two replicas can never
//! both take a job, both finish it, or finish one that was canceled meanwhile.

use std::collections::HashMap;
use std::sync::Arc;

use redis::aio::ConnectionManager;
use redis::{RedisResult, Script};

const COMMON: &str = include_str!("common.lua");

fn script(body: &str) -> Script {
    Script::new(&format!("{COMMON}\n{body}"))
}

struct Set {
    submit: Script,
    claim: Script,
    renew: Script,
    finish: Script,
    cancel: Script,
    view: Script,
    stats: Script,
}

/// A connection (reconnecting by itself) and the scripts, for one key prefix. Cheap to clone.
#[derive(Clone)]
pub struct Redis {
    conn: ConnectionManager,
    prefix: String,
    scripts: Arc<Set>,
}

/// What [`Redis::submit`] did.
#[derive(Debug, PartialEq)]
pub enum Submitted {
    /// Queued, at this 1-based position among all waiting jobs.
    Queued(usize),
    /// Refused: this many jobs wait already.
    Full(usize),
    /// Refused: the job's owner has this many jobs queued or running, its limit.
    OwnerBusy(usize),
    Exists,
}

/// What [`Redis::claim`] found.
#[derive(Debug, PartialEq)]
pub enum Claimed {
    Run(Run),
    /// A job whose last allowed attempt's worker died too: failed now.
    Failed {
        id: String,
    },
    /// The entry of a job already finished or canceled, cleared.
    Cleaned {
        id: String,
        state: String,
        volume: String,
    },
    /// An entry without a record, cleared.
    Dropped,
}

/// A job this consumer now runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    pub id: String,
    /// Names this run: the compare-and-set of renewals and of the finish.
    pub token: String,
    pub spec: String,
    pub record: String,
    pub attempt: u32,
}

/// What the job is when a worker renews its lease.
#[derive(Debug, PartialEq)]
pub enum Lease {
    Held,
    Canceled,
    /// Another run has it, or it is gone.
    Lost,
}

/// What [`Redis::finish`] found.
#[derive(Debug, PartialEq)]
pub enum Finished {
    /// Recorded.
    Done,
    /// Not this run's to record: the job's state and volume now.
    Other {
        state: String,
        volume: String,
    },
    Gone,
}

/// What [`Redis::cancel`] did.
#[derive(Debug, PartialEq)]
pub enum Cancel {
    /// Canceled; it was queued (`false`) or running (`true`).
    Canceled {
        was_running: bool,
    },
    /// Already in this final state.
    Final(String),
    None,
}

/// A job's stored fields with the server's time.
pub struct View {
    pub fields: HashMap<String, String>,
    pub now_ms: i64,
    /// 0-based among the waiting jobs.
    pub rank: Option<usize>,
}

/// The shared queue's numbers.
pub struct Stats {
    pub waiting: usize,
    pub running: usize,
    pub oldest_ms: Option<i64>,
    /// Waiting per class, in [`super::CLASSES`] order.
    pub classes: Vec<usize>,
    /// `state|method` → jobs.
    pub counts: Vec<(String, i64)>,
}

fn pairs(flat: Vec<String>) -> impl Iterator<Item = (String, String)> {
    let mut it = flat.into_iter();
    std::iter::from_fn(move || Some((it.next()?, it.next()?)))
}

impl Redis {
    pub fn new(conn: ConnectionManager, prefix: &str) -> Redis {
        Redis {
            conn,
            prefix: prefix.to_string(),
            scripts: Arc::new(Set {
                submit: script(include_str!("submit.lua")),
                claim: script(include_str!("claim.lua")),
                renew: script(include_str!("renew.lua")),
                finish: script(include_str!("finish.lua")),
                cancel: script(include_str!("cancel.lua")),
                view: script(include_str!("view.lua")),
                stats: script(include_str!("stats.lua")),
            }),
        }
    }

    /// The pub/sub channel of queue events (`new`, `done <id>`).
    pub fn events_channel(&self) -> String {
        format!("{}:events", self.prefix)
    }

    /// Waiting jobs (a cheap look before an upload is stored).
    pub async fn waiting(&self) -> RedisResult<usize> {
        redis::cmd("ZCARD")
            .arg(format!("{}:queued", self.prefix))
            .query_async(&mut self.conn.clone())
            .await
    }

    /// Creates the consumer group of every class's stream, if missing.
    pub async fn ensure_groups(&self) -> RedisResult<()> {
        for class in super::CLASSES {
            let r: RedisResult<()> = redis::cmd("XGROUP")
                .arg("CREATE")
                .arg(format!("{}:stream:{class}", self.prefix))
                .arg("workers")
                .arg("0")
                .arg("MKSTREAM")
                .query_async(&mut self.conn.clone())
                .await;
            match r {
                Err(e) if e.code() == Some("BUSYGROUP") => {}
                other => other?,
            }
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    pub async fn submit(
        &self,
        id: &str,
        capacity: usize,
        class: &str,
        cost: f64,
        method: &str,
        record: &str,
        spec: &str,
        owner: Option<&crate::app::queue::Owner>,
    ) -> RedisResult<Submitted> {
        let (what, n): (String, usize) = self
            .scripts
            .submit
            .arg(&self.prefix)
            .arg(id)
            .arg(capacity)
            .arg(class)
            .arg(format!("{cost:.0}"))
            .arg(method)
            .arg(record)
            .arg(spec)
            .arg(owner.map_or("", |o| o.name.as_str()))
            .arg(owner.map_or(0, |o| o.max_jobs))
            .invoke_async(&mut self.conn.clone())
            .await?;
        Ok(match what.as_str() {
            "ok" => Submitted::Queued(n),
            "full" => Submitted::Full(n),
            "owner" => Submitted::OwnerBusy(n),
            _ => Submitted::Exists,
        })
    }

    /// The next job for `consumer` (see claim.lua).
    pub async fn claim(
        &self,
        consumer: &str,
        lease_ms: u64,
        max_attempts: u32,
        credit: f64,
        ttl_s: u64,
        lease_s: f64,
    ) -> RedisResult<Option<Claimed>> {
        let r: Option<Vec<String>> = self
            .scripts
            .claim
            .arg(&self.prefix)
            .arg(consumer)
            .arg(lease_ms)
            .arg(max_attempts)
            .arg(format!("{credit:.0}"))
            .arg(ttl_s)
            .arg(lease_s)
            .invoke_async(&mut self.conn.clone())
            .await?;
        let Some(mut r) = r else { return Ok(None) };
        let mut take = |i: usize| r.get_mut(i).map(std::mem::take).unwrap_or_default();
        let kind = take(0);
        Ok(Some(match kind.as_str() {
            "run" => Claimed::Run(Run {
                id: take(1),
                token: take(2),
                spec: take(5),
                record: take(6),
                attempt: take(7).parse().unwrap_or(1),
            }),
            "failed" => Claimed::Failed { id: take(1) },
            "cleaned" => Claimed::Cleaned {
                id: take(1),
                state: take(2),
                volume: take(3),
            },
            _ => Claimed::Dropped,
        }))
    }

    pub async fn renew(
        &self,
        id: &str,
        token: &str,
        consumer: &str,
        progress: f64,
    ) -> RedisResult<Lease> {
        let r: String = self
            .scripts
            .renew
            .arg(&self.prefix)
            .arg(id)
            .arg(token)
            .arg(consumer)
            .arg(format!("{progress:.6}"))
            .invoke_async(&mut self.conn.clone())
            .await?;
        Ok(match r.as_str() {
            "ok" => Lease::Held,
            "canceled" => Lease::Canceled,
            _ => Lease::Lost,
        })
    }

    #[allow(clippy::too_many_arguments)]
    pub async fn finish(
        &self,
        id: &str,
        token: &str,
        state: &str,
        volume: &str,
        error: &str,
        progress: f64,
        ttl_s: u64,
    ) -> RedisResult<Finished> {
        let r: Vec<String> = self
            .scripts
            .finish
            .arg(&self.prefix)
            .arg(id)
            .arg(token)
            .arg(state)
            .arg(volume)
            .arg(error)
            .arg(format!("{progress:.6}"))
            .arg(ttl_s)
            .invoke_async(&mut self.conn.clone())
            .await?;
        let mut it = r.into_iter();
        Ok(match it.next().as_deref() {
            Some("done") => Finished::Done,
            Some("other") => Finished::Other {
                state: it.next().unwrap_or_default(),
                volume: it.next().unwrap_or_default(),
            },
            _ => Finished::Gone,
        })
    }

    pub async fn cancel(&self, id: &str, ttl_s: u64) -> RedisResult<Cancel> {
        let r: Vec<String> = self
            .scripts
            .cancel
            .arg(&self.prefix)
            .arg(id)
            .arg(ttl_s)
            .invoke_async(&mut self.conn.clone())
            .await?;
        let mut it = r.into_iter();
        Ok(match (it.next().as_deref(), it.next()) {
            (Some("canceled"), was) => Cancel::Canceled {
                was_running: was.as_deref() == Some("running"),
            },
            (Some("final"), Some(state)) => Cancel::Final(state),
            _ => Cancel::None,
        })
    }

    pub async fn view(&self, id: &str) -> RedisResult<View> {
        let (fields, now_ms, rank): (Vec<String>, i64, i64) = self
            .scripts
            .view
            .arg(&self.prefix)
            .arg(id)
            .invoke_async(&mut self.conn.clone())
            .await?;
        Ok(View {
            fields: pairs(fields).collect(),
            now_ms,
            rank: usize::try_from(rank).ok(),
        })
    }

    pub async fn stats(&self) -> RedisResult<Stats> {
        let (waiting, running, oldest, classes, counts): (
            usize,
            usize,
            i64,
            Vec<usize>,
            Vec<String>,
        ) = self
            .scripts
            .stats
            .arg(&self.prefix)
            .invoke_async(&mut self.conn.clone())
            .await?;
        Ok(Stats {
            waiting,
            running,
            oldest_ms: (oldest >= 0).then_some(oldest),
            classes,
            counts: pairs(counts)
                .filter_map(|(k, v)| Some((k, v.parse().ok()?)))
                .collect(),
        })
    }
}
