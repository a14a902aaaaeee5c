//! The preview's own accept loop around hyper, for what `axum::serve` does
//! not do: a cap on open connections, a header-read timeout, and closing
//! connections that have no request in progress (idle keep-alive, partial
//! headers) or whose client stopped reading the response. At the cap, the connection idle
//! the longest makes room, so a real request is answered even while
//! hundreds of idle sockets are held open.

use std::collections::HashMap;
use std::convert::Infallible;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use axum::Router;
use axum::body::Body;
use bytes::Bytes;
use hyper::body::{Frame, Incoming, SizeHint};
use hyper_util::rt::{TokioIo, TokioTimer};
use tokio::io::AsyncWriteExt;
use tokio::net::TcpListener;
use tokio::sync::Notify;
use tower::ServiceExt;

/// Open connections at most (with the common limit of 1024 open files,
/// room is left for the scene's files and the watcher).
pub const MAX_CONNECTIONS: usize = 128;
/// Time to send a whole request header.
pub const HEADER_TIMEOUT: Duration = Duration::from_secs(10);
/// A connection with no request in progress (and no response being
/// written) for this long is closed.
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(10);
/// A response the client has not read any of for this long is abandoned
/// (event streams send a comment every 15 s, so a live page never stalls).
pub const STALL_TIMEOUT: Duration = Duration::from_secs(30);

/// The local address a request came in on (the Host check of network mode).
#[derive(Clone, Copy, Debug)]
pub struct LocalAddr(pub SocketAddr);

struct Conn {
    /// Requests in progress, responses included until their body is sent.
    active: AtomicUsize,
    /// Response bodies being sent.
    sending: AtomicUsize,
    /// The last time a request started or a response made progress.
    last: Mutex<Instant>,
    close: Notify,
}

impl Conn {
    fn touch(&self) {
        *self.last.lock().unwrap_or_else(|p| p.into_inner()) = Instant::now();
    }

    /// Whether to close it: idle too long, or a response stalled.
    fn expired(&self) -> bool {
        let last = *self.last.lock().unwrap_or_else(|p| p.into_inner());
        if self.active.load(Ordering::SeqCst) == 0 {
            last.elapsed() > IDLE_TIMEOUT
        } else {
            self.sending.load(Ordering::SeqCst) > 0 && last.elapsed() > STALL_TIMEOUT
        }
    }

    fn idle_since(&self) -> Option<Instant> {
        (self.active.load(Ordering::SeqCst) == 0)
            .then(|| *self.last.lock().unwrap_or_else(|p| p.into_inner()))
    }
}

/// The open connections.
#[derive(Default)]
pub struct Connections {
    open: Mutex<HashMap<u64, Arc<Conn>>>,
    next: AtomicU64,
}

impl Connections {
    /// Connections open now.
    pub fn count(&self) -> usize {
        self.lock().len()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<u64, Arc<Conn>>> {
        self.open.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Makes room for one more: closes the connection idle the longest.
    /// False when every connection is busy.
    fn make_room(&self) -> bool {
        let mut open = self.lock();
        if open.len() < MAX_CONNECTIONS {
            return true;
        }
        let oldest = open
            .iter()
            .filter_map(|(id, c)| c.idle_since().map(|t| (t, *id)))
            .min();
        match oldest.and_then(|(_, id)| open.remove(&id)) {
            Some(conn) => {
                conn.close.notify_one();
                true
            }
            None => false,
        }
    }
}

/// Counts a request as in progress on its connection until dropped.
struct Busy(Arc<Conn>);

impl Busy {
    fn new(conn: &Arc<Conn>) -> Busy {
        conn.active.fetch_add(1, Ordering::SeqCst);
        conn.touch();
        Busy(Arc::clone(conn))
    }
}

impl Drop for Busy {
    fn drop(&mut self) {
        self.0.touch();
        self.0.active.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A response body that keeps its connection busy until it is sent, and
/// counts each frame as progress.
struct Tracked {
    inner: Body,
    busy: Busy,
}

impl Tracked {
    fn new(inner: Body, busy: Busy) -> Tracked {
        busy.0.sending.fetch_add(1, Ordering::SeqCst);
        busy.0.touch();
        Tracked { inner, busy }
    }
}

impl Drop for Tracked {
    fn drop(&mut self) {
        self.busy.0.sending.fetch_sub(1, Ordering::SeqCst);
    }
}

impl hyper::body::Body for Tracked {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        let this = self.get_mut();
        let polled = Pin::new(&mut this.inner).poll_frame(cx);
        if polled.is_ready() {
            this.busy.0.touch();
        }
        polled
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.inner.size_hint()
    }
}

/// Accepts connections for ever.
pub async fn serve(listener: TcpListener, router: Router, connections: Arc<Connections>) {
    loop {
        let stream = match listener.accept().await {
            Ok((stream, _)) => stream,
            // Out of file descriptors, or a connection reset before it was
            // accepted: wait a little rather than spin.
            Err(_) => {
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        if !connections.make_room() {
            tokio::spawn(refuse(stream));
            continue;
        }
        let Ok(local) = stream.local_addr() else {
            continue;
        };
        let conn = Arc::new(Conn {
            active: AtomicUsize::new(0),
            sending: AtomicUsize::new(0),
            last: Mutex::new(Instant::now()),
            close: Notify::new(),
        });
        let id = connections.next.fetch_add(1, Ordering::SeqCst);
        connections.lock().insert(id, Arc::clone(&conn));
        let (router, connections) = (router.clone(), Arc::clone(&connections));
        tokio::spawn(async move {
            let service = {
                let conn = Arc::clone(&conn);
                hyper::service::service_fn(move |request: hyper::Request<Incoming>| {
                    let busy = Busy::new(&conn);
                    let router = router.clone();
                    async move {
                        let mut request = request.map(Body::new);
                        request.extensions_mut().insert(LocalAddr(local));
                        let response = match router.oneshot(request).await {
                            Ok(r) => r,
                            Err(never) => match never {},
                        };
                        Ok::<_, Infallible>(
                            response.map(|inner| Body::new(Tracked::new(inner, busy))),
                        )
                    }
                })
            };
            let mut builder = hyper::server::conn::http1::Builder::new();
            builder
                .timer(TokioTimer::new())
                .header_read_timeout(HEADER_TIMEOUT);
            let connection = builder.serve_connection(TokioIo::new(stream), service);
            tokio::pin!(connection);
            loop {
                tokio::select! {
                    _ = &mut connection => break,
                    _ = conn.close.notified() => break,
                    _ = tokio::time::sleep(Duration::from_secs(1)) => {
                        if conn.expired() {
                            break;
                        }
                    }
                }
            }
            connections.lock().remove(&id);
        });
    }
}

/// Every connection is busy: say so and close.
async fn refuse(mut stream: tokio::net::TcpStream) {
    let body = "the preview has too many connections open; try again\n";
    let response = format!(
        "HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\nRetry-After: 1\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    let _ = tokio::time::timeout(
        Duration::from_secs(1),
        stream.write_all(response.as_bytes()),
    )
    .await;
}
