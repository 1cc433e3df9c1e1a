//! What keeps one client from costing the others: every connection's reads and writes are
//! watched, and a connection is closed when
//! - it has not sent a whole first request head within `Options::header_timeout` of being
//!   accepted (silent sockets, a byte now and then, an HTTP/2 preface and nothing after);
//! - nothing has moved either way for `Options::idle_timeout` while no request of it is being
//!   answered (keep-alive between requests, a client that stops reading its answer);
//! - its client has hung up while its request is still being worked on (the work is dropped
//!   with it: a box download stops at its next node);
//! - the server is full and it is the connection idle the longest (shed for a new client).
//!
//! Bytes read from files for answers are taken from a [`Budget`], for the connection and for
//! the whole server, before they are read, and given back when the connection has written them:
//! clients that ask for much and read slowly wait for their turn instead of filling memory.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, Weak};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::sync::{Notify, OwnedSemaphorePermit, Semaphore};

/// How often a connection's watchdog looks at it.
pub(crate) const TICK: Duration = Duration::from_millis(200);
/// A connection idle at least this long may be shed for a new one when the server is full.
pub(crate) const SHED_AFTER: Duration = Duration::from_millis(500);

/// One connection's activity, shared by its reader and writer, its requests and its watchdog.
pub(crate) struct Activity {
    epoch: Instant,
    /// Milliseconds from `epoch` to the last byte read or written.
    last: AtomicU64,
    /// Requests of this connection being worked on (before their answer's head is ready).
    busy: AtomicUsize,
    /// Requests received so far.
    requests: AtomicU64,
    /// Told when the server sheds this connection.
    pub(crate) shed: Notify,
}

impl Activity {
    pub(crate) fn new() -> Arc<Activity> {
        Arc::new(Activity {
            epoch: Instant::now(),
            last: AtomicU64::new(0),
            busy: AtomicUsize::new(0),
            requests: AtomicU64::new(0),
            shed: Notify::new(),
        })
    }

    fn touch(&self) {
        self.last
            .store(self.epoch.elapsed().as_millis() as u64, Ordering::Relaxed);
    }

    pub(crate) fn idle(&self) -> Duration {
        let now = self.epoch.elapsed().as_millis() as u64;
        Duration::from_millis(now.saturating_sub(self.last.load(Ordering::Relaxed)))
    }

    pub(crate) fn age(&self) -> Duration {
        self.epoch.elapsed()
    }

    pub(crate) fn busy(&self) -> bool {
        self.busy.load(Ordering::Relaxed) > 0
    }

    pub(crate) fn requests(&self) -> u64 {
        self.requests.load(Ordering::Relaxed)
    }

    /// Marks a request as being worked on until the guard is dropped.
    pub(crate) fn request(self: &Arc<Self>) -> Busy {
        self.requests.fetch_add(1, Ordering::Relaxed);
        self.busy.fetch_add(1, Ordering::Relaxed);
        self.touch();
        Busy(self.clone())
    }
}

pub(crate) struct Busy(Arc<Activity>);

impl Drop for Busy {
    fn drop(&mut self) {
        self.0.busy.fetch_sub(1, Ordering::Relaxed);
        self.0.touch();
    }
}

/// The server's open connections, for shedding the idlest when full.
#[derive(Default)]
pub(crate) struct Registry(Mutex<Vec<Weak<Activity>>>);

impl Registry {
    pub(crate) fn add(&self, a: &Arc<Activity>) {
        let mut v = self.0.lock().expect("registry lock");
        v.retain(|w| w.strong_count() > 0);
        v.push(Arc::downgrade(a));
    }

    /// Tells the connection idle the longest (at least [`SHED_AFTER`], no request being worked
    /// on) to close; false when there is none.
    pub(crate) fn shed_idlest(&self) -> bool {
        let v = self.0.lock().expect("registry lock");
        let idlest = v
            .iter()
            .filter_map(Weak::upgrade)
            .filter(|a| !a.busy() && a.idle() >= SHED_AFTER)
            .max_by_key(|a| a.idle());
        match idlest {
            Some(a) => {
                a.shed.notify_one();
                true
            }
            None => false,
        }
    }
}

/// A socket whose reads and writes touch its [`Activity`].
pub(crate) struct Watched<T> {
    pub(crate) inner: T,
    pub(crate) activity: Arc<Activity>,
}

impl<T: AsyncRead + Unpin> AsyncRead for Watched<T> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        let r = Pin::new(&mut self.inner).poll_read(cx, buf);
        if matches!(r, Poll::Ready(Ok(()))) && buf.filled().len() > before {
            self.activity.touch();
        }
        r
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for Watched<T> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let r = Pin::new(&mut self.inner).poll_write(cx, buf);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            self.activity.touch();
        }
        r
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let r = Pin::new(&mut self.inner).poll_write_vectored(cx, bufs);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            self.activity.touch();
        }
        r
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

/// Whether the peer of socket `fd` has closed its side (a read would give end of file, or the
/// connection was reset).
pub(crate) fn peer_closed(fd: std::os::fd::RawFd) -> bool {
    let mut b = [0u8; 1];
    // SAFETY: `fd` is an open socket for as long as its connection runs (the caller's), and
    // the buffer is valid for one byte; MSG_PEEK leaves the data where it is.
    let n = unsafe {
        libc::recv(
            fd,
            b.as_mut_ptr().cast(),
            1,
            libc::MSG_PEEK | libc::MSG_DONTWAIT,
        )
    };
    // End of file: closed; reset (a client that closed before reading what it had been sent):
    // closed too.
    n == 0
        || (n < 0
            && matches!(
                std::io::Error::last_os_error().raw_os_error(),
                Some(libc::ECONNRESET | libc::ENOTCONN | libc::EPIPE)
            ))
}

/// Why a connection's watchdog closed it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Closed {
    Done,
    NoRequest,
    Idle,
    HungUp,
    Shed,
}

/// Runs connection `conn` under its watchdog until it ends or must be closed.
pub(crate) async fn watch<F: Future>(
    conn: F,
    activity: &Activity,
    fd: std::os::fd::RawFd,
    header_timeout: Duration,
    idle_timeout: Duration,
) -> Closed {
    tokio::pin!(conn);
    loop {
        tokio::select! {
            _ = &mut conn => return Closed::Done,
            _ = activity.shed.notified() => return Closed::Shed,
            _ = tokio::time::sleep(TICK) => {
                if activity.requests() == 0 && activity.age() > header_timeout {
                    return Closed::NoRequest;
                }
                if activity.busy() {
                    if peer_closed(fd) {
                        return Closed::HungUp;
                    }
                } else if activity.idle() > idle_timeout {
                    return Closed::Idle;
                }
            }
        }
    }
}

/// Bytes that answers may hold in memory, per connection and in all, in KiB.
#[derive(Clone)]
pub(crate) struct Budget {
    all: Arc<Semaphore>,
    conn: Arc<Semaphore>,
}

/// Bytes taken from a [`Budget`], given back when dropped.
pub(crate) struct Held(
    #[allow(dead_code)] OwnedSemaphorePermit,
    #[allow(dead_code)] OwnedSemaphorePermit,
);

/// Most bytes one connection's answers hold at once.
pub(crate) const PER_CONNECTION: usize = 16 << 20;

impl Budget {
    pub(crate) fn new(all: Arc<Semaphore>) -> Budget {
        Budget {
            all,
            conn: Arc::new(Semaphore::new(PER_CONNECTION >> 10)),
        }
    }

    pub(crate) fn kib(bytes: usize) -> u32 {
        bytes.div_ceil(1024).max(1) as u32
    }

    /// Waits until `bytes` (at most [`PER_CONNECTION`]) may be held.
    pub(crate) async fn take(&self, bytes: usize) -> Held {
        let n = Budget::kib(bytes.min(PER_CONNECTION));
        // The connection's share first: one connection's requests queue behind each other
        // before they take from everyone's.
        let c = self
            .conn
            .clone()
            .acquire_many_owned(n)
            .await
            .expect("never closed");
        let a = self
            .all
            .clone()
            .acquire_many_owned(n)
            .await
            .expect("never closed");
        Held(c, a)
    }
}

/// Bytes that give their budget back when the connection drops them (written or abandoned).
pub(crate) struct Owned {
    pub(crate) data: Vec<u8>,
    pub(crate) _held: Held,
}

impl AsRef<[u8]> for Owned {
    fn as_ref(&self) -> &[u8] {
        &self.data
    }
}
