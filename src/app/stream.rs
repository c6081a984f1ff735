//! Bytes made on a blocking thread and sent as a response body while they are made: the
//! converted downloads and the extracted meshes. The writer runs at most a few chunks ahead of
//! the client; a client that stops reading stops it, and one that goes away ends it (its writes
//! fail with `BrokenPipe`).

use bytes::Bytes;

use super::store::{ByteStream, StoreError};

/// Bytes per chunk.
pub const CHUNK: usize = 256 << 10;

/// Chunks made ahead of the client at most.
const AHEAD: usize = 4;

/// The bytes `write` writes, as a stream: `write` runs on the blocking pool. An error other
/// than the client's going away ends the stream with that error (the caller logs it).
pub fn from_writer(
    write: impl FnOnce(&mut ChunkSender) -> std::io::Result<()> + Send + 'static,
) -> ByteStream {
    let (tx, rx) = tokio::sync::mpsc::channel::<Result<Bytes, StoreError>>(AHEAD);
    tokio::task::spawn_blocking(move || {
        let mut w = ChunkSender {
            buf: Vec::with_capacity(CHUNK),
            tx,
        };
        match write(&mut w).and_then(|()| w.send()) {
            // The client went away (the receiver is gone): nothing to tell.
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
            Err(e) => {
                let _ = w.tx.blocking_send(Err(StoreError::Io(e)));
            }
            Ok(()) => {}
        }
    });
    Box::pin(futures_util::stream::unfold(rx, |mut rx| async move {
        rx.recv().await.map(|c| (c, rx))
    }))
}

/// An `io::Write` that hands its bytes to a channel in chunks (from a blocking thread); a
/// closed channel is `BrokenPipe`, which stops the writer.
pub struct ChunkSender {
    buf: Vec<u8>,
    tx: tokio::sync::mpsc::Sender<Result<Bytes, StoreError>>,
}

impl ChunkSender {
    fn send(&mut self) -> std::io::Result<()> {
        if self.buf.is_empty() {
            return Ok(());
        }
        let chunk = std::mem::replace(&mut self.buf, Vec::with_capacity(CHUNK));
        self.tx
            .blocking_send(Ok(Bytes::from(chunk)))
            .map_err(|_| std::io::Error::from(std::io::ErrorKind::BrokenPipe))
    }
}

impl std::io::Write for ChunkSender {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        let room = CHUNK - self.buf.len();
        let n = b.len().min(room);
        self.buf.extend_from_slice(&b[..n]);
        if self.buf.len() == CHUNK {
            self.send()?;
        }
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}
