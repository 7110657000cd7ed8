//! Serving connections: hyper's HTTP/1.1 connection (axum's `serve` has no
//! timeouts) with a timer, so that a connection idle between requests, or
//! one whose request head is slow, is closed after the idle timeout; and
//! [`JsonErrors`] around the socket, so that the few answers hyper writes
//! on its own (400 for a malformed request, 414 for a URI above 64 KiB,
//! 431 for a head above its buffer) carry `{"error", "kind"}` like every
//! other.

use std::io;
use std::pin::Pin;
use std::task::{Context, Poll, ready};
use std::time::Duration;

use axum::Router;
use axum::http::StatusCode;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpListener;

/// Accepts connections on `listener` and serves `router` on each, until
/// the process stops.
pub async fn serve(listener: TcpListener, router: Router, idle_timeout: Duration) {
    let mut http = http1::Builder::new();
    http.timer(TokioTimer::new())
        .header_read_timeout(idle_timeout);
    loop {
        let stream = match listener.accept().await {
            Ok((stream, _)) => stream,
            Err(e) => {
                // Out of file descriptors, say: wait rather than spin.
                eprintln!("warning: accepting a connection: {e}");
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        // Frames are small writes answered at once.
        let _ = stream.set_nodelay(true);
        let connection = http.serve_connection(
            TokioIo::new(JsonErrors::new(stream)),
            TowerToHyperService::new(router.clone()),
        );
        tokio::spawn(async move {
            let _ = connection.await;
        });
    }
}

/// A socket whose writes pass through unchanged, except an error answer
/// that hyper composed itself — a 4xx/5xx head with `content-length: 0`
/// and no body, written alone — which gets a JSON body. The editor's own
/// error answers always have a JSON body ([`super::guard::json_errors`]),
/// so they never match.
pub struct JsonErrors<T> {
    inner: T,
    /// A rewritten answer still to be written.
    pending: Vec<u8>,
    written: usize,
}

impl<T> JsonErrors<T> {
    /// Wraps `inner`.
    pub fn new(inner: T) -> Self {
        JsonErrors {
            inner,
            pending: Vec::new(),
            written: 0,
        }
    }
}

impl<T: AsyncWrite + Unpin> JsonErrors<T> {
    fn poll_pending(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        while self.written < self.pending.len() {
            let n =
                ready!(Pin::new(&mut self.inner).poll_write(cx, &self.pending[self.written..]))?;
            if n == 0 {
                return Poll::Ready(Err(io::ErrorKind::WriteZero.into()));
            }
            self.written += n;
        }
        self.pending.clear();
        self.written = 0;
        Poll::Ready(Ok(()))
    }

    /// Takes `buf` as a rewritten answer if it is hyper's own error answer.
    fn take_automatic_error(
        &mut self,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Option<Poll<io::Result<usize>>> {
        let json = automatic_error_as_json(buf)?;
        self.pending = json;
        self.written = 0;
        if let Poll::Ready(Err(e)) = self.poll_pending(cx) {
            return Some(Poll::Ready(Err(e)));
        }
        Some(Poll::Ready(Ok(buf.len())))
    }
}

impl<T: AsyncRead + Unpin> AsyncRead for JsonErrors<T> {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_read(cx, buf)
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for JsonErrors<T> {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        ready!(this.poll_pending(cx))?;
        if let Some(done) = this.take_automatic_error(cx, buf) {
            return done;
        }
        Pin::new(&mut this.inner).poll_write(cx, buf)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        ready!(this.poll_pending(cx))?;
        let mut nonempty = bufs.iter().filter(|b| !b.is_empty());
        if let (Some(only), None) = (nonempty.next(), nonempty.next())
            && let Some(done) = this.take_automatic_error(cx, only)
        {
            return done;
        }
        Pin::new(&mut this.inner).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        ready!(this.poll_pending(cx))?;
        Pin::new(&mut this.inner).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        ready!(this.poll_pending(cx))?;
        Pin::new(&mut this.inner).poll_shutdown(cx)
    }
}

/// `buf` with a JSON body if it is exactly an HTTP/1.x 4xx/5xx head with
/// `content-length: 0` and no content type.
fn automatic_error_as_json(buf: &[u8]) -> Option<Vec<u8>> {
    let rest = buf
        .strip_prefix(b"HTTP/1.1 ")
        .or_else(|| buf.strip_prefix(b"HTTP/1.0 "))?;
    if !matches!(rest.first(), Some(b'4' | b'5')) || buf.len() > 4096 {
        return None;
    }
    let head = std::str::from_utf8(buf.strip_suffix(b"\r\n\r\n")?).ok()?;
    let mut lines = head.split("\r\n");
    let status_line = lines.next()?;
    let mut kept = Vec::new();
    let mut empty = false;
    for line in lines {
        let (name, value) = line.split_once(':')?;
        if name.eq_ignore_ascii_case("content-length") {
            if value.trim() != "0" {
                return None;
            }
            empty = true;
        } else if name.eq_ignore_ascii_case("content-type")
            || name.eq_ignore_ascii_case("transfer-encoding")
        {
            return None;
        } else {
            kept.push(line);
        }
    }
    if !empty {
        return None;
    }
    let status = StatusCode::from_u16(status_line.get(9..12)?.parse().ok()?).ok()?;
    let message = match status {
        StatusCode::BAD_REQUEST => "malformed HTTP request".to_string(),
        StatusCode::URI_TOO_LONG => format!(
            "the request URI is too long (limit {} bytes)",
            super::guard::MAX_URI_BYTES
        ),
        StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE => "the request head is too large".to_string(),
        other => super::api_error::status_message(other),
    };
    let body = super::api_error::error_json(super::api_error::status_kind(status), &message);
    let mut out = String::with_capacity(head.len() + body.len() + 64);
    out.push_str(status_line);
    out.push_str("\r\n");
    for line in kept {
        out.push_str(line);
        out.push_str("\r\n");
    }
    out.push_str(&format!(
        "content-type: application/json\r\ncontent-length: {}\r\n\r\n{body}",
        body.len()
    ));
    Some(out.into_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hypers_own_error_heads_get_a_json_body() {
        let head = b"HTTP/1.1 414 URI Too Long\r\ncontent-length: 0\r\ndate: Thu, 01 Jan 2026 00:00:00 GMT\r\n\r\n";
        let out = String::from_utf8(automatic_error_as_json(head).unwrap()).unwrap();
        let (h, body) = out.split_once("\r\n\r\n").unwrap();
        assert!(h.starts_with("HTTP/1.1 414 URI Too Long\r\n"), "{h}");
        assert!(h.contains("date: Thu"), "{h}");
        assert!(!h.contains("content-length: 0"), "{h}");
        assert!(
            h.contains(&format!("content-length: {}", body.len())),
            "{h}"
        );
        let v: serde_json::Value = serde_json::from_str(body).unwrap();
        assert_eq!(v["kind"], "uri-too-long");
        assert!(v["error"].as_str().unwrap().contains("too long"));
    }

    #[test]
    fn other_writes_pass_through() {
        for buf in [
            &b"HTTP/1.1 200 OK\r\ncontent-length: 0\r\n\r\n"[..],
            b"HTTP/1.1 404 Not Found\r\ncontent-type: application/json\r\ncontent-length: 2\r\n\r\n{}",
            b"HTTP/1.1 404 Not Found\r\ncontent-type: application/json\r\ncontent-length: 0\r\n\r\n",
            b"HTTP/1.1 400 Bad Request\r\ncontent-length: 12\r\n\r\n",
            b"HTTP/1.1 400 Bad Request\r\ntransfer-encoding: chunked\r\n\r\n",
            b"0\r\n\r\n",
            b"{\"error\": \"x\"}",
            b"",
        ] {
            assert!(automatic_error_as_json(buf).is_none(), "{:?}", String::from_utf8_lossy(buf));
        }
    }

    /// Accepts at most 7 bytes a write.
    struct Trickle(Vec<u8>);

    impl AsyncWrite for Trickle {
        fn poll_write(
            self: Pin<&mut Self>,
            _: &mut Context<'_>,
            buf: &[u8],
        ) -> Poll<io::Result<usize>> {
            let n = buf.len().min(7);
            self.get_mut().0.extend_from_slice(&buf[..n]);
            Poll::Ready(Ok(n))
        }
        fn poll_flush(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
            Poll::Ready(Ok(()))
        }
        fn poll_shutdown(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
            Poll::Ready(Ok(()))
        }
    }

    #[test]
    fn a_rewritten_answer_is_written_whole_before_what_follows() {
        let mut w = JsonErrors::new(Trickle(Vec::new()));
        let head = b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\n\r\n";
        let waker = std::task::Waker::noop();
        let mut cx = Context::from_waker(waker);
        let n = Pin::new(&mut w).poll_write(&mut cx, head);
        assert!(matches!(n, Poll::Ready(Ok(k)) if k == head.len()));
        let mut rest: &[u8] = b"after";
        while !rest.is_empty() {
            let Poll::Ready(Ok(k)) = Pin::new(&mut w).poll_write(&mut cx, rest) else {
                panic!("a write failed")
            };
            rest = &rest[k..];
        }
        assert!(Pin::new(&mut w).poll_flush(&mut cx).is_ready());
        let out = String::from_utf8(w.inner.0).unwrap();
        assert!(
            out.starts_with("HTTP/1.1 400 Bad Request\r\ncontent-type: application/json\r\n"),
            "{out}"
        );
        assert!(out.ends_with("\"}after"), "{out}");
    }
}
