//! A running job's lease on the shared queue: its renewal while it runs (which also reports
//! progress and hears a cancel or a takeover) and the last check before its volume is stored.
//! Not here: taking and finishing jobs (`super`), the scripts that change their state.

use std::time::Duration;

use async_trait::async_trait;

use super::scripts::{Lease, Redis};
use crate::app::queue::{CommitGuard, Error, ErrorKind, Result};
use crate::cancel::Control;

/// Renews a run's lease until it ends; a cancel or a lost lease stops the run (its control).
pub(super) async fn renew(
    redis: Redis,
    consumer: String,
    id: String,
    token: String,
    control: Control,
    every: Duration,
) {
    let mut failing = false;
    loop {
        tokio::time::sleep(every).await;
        match redis
            .renew(&id, &token, &consumer, control.progress())
            .await
        {
            Ok(Lease::Held) => failing = false,
            Ok(Lease::Canceled) => {
                tracing::info!(job = %id, "canceled from another replica; stopping");
                control.cancel();
                return;
            }
            Ok(Lease::Lost) => {
                tracing::warn!(job = %id, "lease lost (another replica took the job over); stopping");
                control.cancel();
                return;
            }
            Err(e) => {
                if !failing {
                    tracing::warn!(job = %id, "cannot renew the job's lease: {e}");
                }
                failing = true;
            }
        }
    }
}

/// A run's check before it stores its volume.
pub(super) struct Guard {
    pub(super) redis: Redis,
    pub(super) consumer: String,
    pub(super) id: String,
    pub(super) token: String,
    pub(super) control: Control,
}

#[async_trait]
impl CommitGuard for Guard {
    async fn confirm(&self) -> Result<()> {
        match self
            .redis
            .renew(
                &self.id,
                &self.token,
                &self.consumer,
                self.control.progress(),
            )
            .await
        {
            Ok(Lease::Held) => Ok(()),
            Ok(Lease::Canceled) => {
                self.control.cancel();
                Err(Error::new(ErrorKind::NotCancelable, "canceled"))
            }
            Ok(Lease::Lost) => {
                self.control.cancel();
                Err(Error::internal(
                    "another replica took this job over (this one did not renew its lease in time); this run's result is discarded",
                ))
            }
            // The volume's id is the job's own, so storing it cannot make a second one: the
            // finish (retried until Redis answers) decides whether it stays.
            Err(e) => {
                tracing::warn!(job = %self.id, "cannot confirm the lease before storing: {e}");
                Ok(())
            }
        }
    }
}
