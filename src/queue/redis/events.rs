//! The shared queue's events: a pub/sub subscription of its own that wakes idle workers (`new`)
//! and waiters (`done ID`), resubscribing with backoff. Not here: what the events announce.

use std::time::Duration;

use futures_util::StreamExt;

use super::Inner;

/// Listens to the queue's events (pub/sub, its own connection), reconnecting with backoff:
/// `new` wakes idle workers, `done <id>` wakes waiters. After every (re)subscription everyone
/// looks again, for what happened while nobody listened.
pub(super) async fn listen(client: redis::Client, inner: std::sync::Weak<Inner>) {
    let mut backoff = Duration::from_millis(100);
    loop {
        let Some(channel) = inner.upgrade().map(|i| i.redis.events_channel()) else {
            return;
        };
        match client.get_async_pubsub().await {
            Ok(mut pubsub) => {
                if pubsub.subscribe(&channel).await.is_ok() {
                    backoff = Duration::from_millis(100);
                    if let Some(i) = inner.upgrade() {
                        i.ready.notify_waiters();
                        let _ = i.done.send(String::new());
                    }
                    let mut messages = pubsub.on_message();
                    while let Some(m) = messages.next().await {
                        let Some(i) = inner.upgrade() else { return };
                        let text: String = m.get_payload().unwrap_or_default();
                        if text == "new" {
                            i.ready.notify_waiters();
                        } else if let Some(id) = text.strip_prefix("done ") {
                            i.forget_prepared(id);
                            let _ = i.done.send(id.to_string());
                        }
                    }
                }
            }
            Err(e) => tracing::debug!("queue events: {e}"),
        }
        tokio::time::sleep(backoff).await;
        backoff = (backoff * 2).min(Duration::from_secs(5));
    }
}
