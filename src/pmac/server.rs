//! The emulator's TCP server: the Ethernet protocol, and a plain
//! line-per-command mode on the same port (told apart by the first byte:
//! an Ethernet request starts with 0x40 or 0xC0, a text command with a
//! letter, `&`, `#` or a digit).
//!
//! One thread per connection; each reply is written in ONE write, since
//! clients such as dls-pmaclib read a reply with a single recv.

use crate::pmac::controller::{Emulator, Session};
use crate::pmac::protocol::{self as p, Header};
use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// Most unfetched SENDLINE reply text kept per connection.
const LINE_OUT_MAX: usize = 1 << 16;

/// Faults to inject, for testing a client's recovery.
#[derive(Debug, Clone, Default)]
pub struct Faults {
    /// Close the connection instead of answering the Nth request (counted
    /// over all connections from 1), once.
    pub drop_at: Option<u64>,
    /// Wait this long before every reply ...
    pub delay: Duration,
    /// ... from request N on (0: from the first) ...
    pub delay_from: u64,
    /// ... for this many requests (None: all).
    pub delay_count: Option<u64>,
    /// Reset the controller (`$$$`) on the Nth request, once, whatever it
    /// is doing then.
    pub reset_at: Option<u64>,
    /// Reset the controller (`$$$`) once, on the first request from the
    /// Nth on at which a motion program is running: a reset mid-run
    /// whatever the client's pace. (`reset_at` alone may land while the
    /// client downloads between runs, which loses nothing and stops
    /// nothing, so a test of the mid-run reset could not rely on it.)
    pub reset_mid_run_from: Option<u64>,
    /// Lie once, in the first reply with a number from request N on: every
    /// number in it becomes 99999 (a counter past any job's end), as a
    /// broken proxy might.
    pub lie_at: Option<u64>,
}

/// A running emulator server; dropping it stops accepting connections.
pub struct Server {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    accept: Option<JoinHandle<()>>,
    /// The emulated controller the connections share; tests and pmac-emu
    /// inspect it (time, buffers, event log) while clients talk.
    pub controller: Arc<Mutex<Emulator>>,
}

struct Shared {
    ctl: Arc<Mutex<Emulator>>,
    faults: Faults,
    requests: AtomicU64,
    stop: Arc<AtomicBool>,
    lied: AtomicBool,
    reset_mid_run_done: AtomicBool,
}

impl Server {
    /// Listen on `addr` (port 0 picks a free one) and serve in background
    /// threads.
    pub fn start(addr: SocketAddr, controller: Emulator, faults: Faults) -> io::Result<Server> {
        let listener = TcpListener::bind(addr)?;
        let addr = listener.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let ctl = Arc::new(Mutex::new(controller));
        let shared = Arc::new(Shared {
            ctl: ctl.clone(),
            faults,
            requests: AtomicU64::new(0),
            stop: stop.clone(),
            lied: AtomicBool::new(false),
            reset_mid_run_done: AtomicBool::new(false),
        });
        let accept = std::thread::spawn(move || {
            for conn in listener.incoming() {
                if shared.stop.load(Ordering::SeqCst) {
                    break;
                }
                let Ok(conn) = conn else { continue };
                let sh = shared.clone();
                std::thread::spawn(move || {
                    // A broken connection ends its thread; nothing else.
                    let _ = serve(conn, &sh);
                });
            }
        });
        Ok(Server {
            addr,
            stop,
            accept: Some(accept),
            controller: ctl,
        })
    }

    /// The address it listens on (with the port chosen when 0 was asked).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stop accepting connections (open ones end when their client goes).
    pub fn shutdown(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the blocking accept.
        let _ = TcpStream::connect_timeout(&self.addr, Duration::from_secs(1));
        if let Some(h) = self.accept.take() {
            let _ = h.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn lock(ctl: &Mutex<Emulator>) -> std::sync::MutexGuard<'_, Emulator> {
    // A panic elsewhere must not stop the emulator answering.
    ctl.lock().unwrap_or_else(|e| e.into_inner())
}

/// Apply the lie fault to a reply of request `n`.
fn lie(sh: &Shared, n: u64, r: Result<Vec<String>, u16>) -> Result<Vec<String>, u16> {
    let numeric = |v: &Vec<String>| v.iter().any(|l| l.trim().parse::<f64>().is_ok());
    if sh.faults.lie_at.is_none_or(|k| n < k) || !r.as_ref().is_ok_and(numeric) || sh.lied.swap(true, Ordering::SeqCst)
    {
        return r;
    }
    r.map(|v| {
        v.into_iter()
            .map(|l| {
                if l.trim().parse::<f64>().is_ok() {
                    "99999".to_string()
                } else {
                    l
                }
            })
            .collect()
    })
}

/// Count a request and apply faults; `false` means drop the connection.
fn count(sh: &Shared) -> bool {
    let n = sh.requests.fetch_add(1, Ordering::SeqCst) + 1;
    if sh.faults.reset_at == Some(n) {
        lock(&sh.ctl).reset();
    }
    if sh.faults.reset_mid_run_from.is_some_and(|k| n >= k) && !sh.reset_mid_run_done.load(Ordering::SeqCst) {
        let mut ctl = lock(&sh.ctl);
        // Bring the run up to now first: a program that ended since the
        // last request must not count as running.
        ctl.advance();
        if ctl.running() {
            ctl.reset();
            sh.reset_mid_run_done.store(true, Ordering::SeqCst);
        }
    }
    if !sh.faults.delay.is_zero()
        && n >= sh.faults.delay_from
        && sh.faults.delay_count.is_none_or(|c| n < sh.faults.delay_from + c)
    {
        std::thread::sleep(sh.faults.delay);
    }
    sh.faults.drop_at != Some(n)
}

fn serve(conn: TcpStream, sh: &Shared) -> io::Result<()> {
    conn.set_nodelay(true)?;
    let mut first = [0u8; 1];
    if conn.peek(&mut first)? == 0 {
        return Ok(());
    }
    if matches!(first[0], p::VR_DOWNLOAD | p::VR_UPLOAD) {
        serve_ethernet(conn, sh)
    } else {
        serve_lines(conn, sh)
    }
}

fn serve_lines(conn: TcpStream, sh: &Shared) -> io::Result<()> {
    let mut w = conn.try_clone()?;
    let mut r = BufReader::new(conn);
    let mut sess = Session::default();
    let mut buf = Vec::new();
    loop {
        buf.clear();
        // Lines end with CR or LF; bound the length so a peer cannot
        // make us buffer without end.
        let n = r.by_ref().take(4096).read_until(b'\r', &mut buf)?;
        if n == 0 {
            return Ok(());
        }
        let text = String::from_utf8_lossy(&buf);
        for line in text.split(['\r', '\n']).filter(|l| !l.trim().is_empty()) {
            if !count(sh) {
                return Ok(());
            }
            let n = sh.requests.load(Ordering::SeqCst);
            let reply = lie(sh, n, lock(&sh.ctl).command_line(&mut sess, line));
            w.write_all(&p::frame_reply(&reply))?;
        }
    }
}

fn serve_ethernet(mut conn: TcpStream, sh: &Shared) -> io::Result<()> {
    let mut sess = Session::default();
    // Reply text not yet fetched: GETBUFFER continues it, GETLINE reads it.
    let mut rest: Vec<u8> = Vec::new();
    let mut line_out: Vec<u8> = Vec::new();
    let mut hdr = [0u8; 8];
    let mut payload = Vec::new();
    loop {
        match conn.read_exact(&mut hdr) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(e) => return Err(e),
        }
        let h = Header::decode(&hdr);
        payload.clear();
        if h.has_payload() {
            payload.resize(usize::from(h.length), 0);
            conn.read_exact(&mut payload)?;
        }
        if !count(sh) {
            return Ok(());
        }
        let reply: Vec<u8> = match h.request {
            p::GETRESPONSE => {
                let cmd = text_of(&payload);
                let n = sh.requests.load(Ordering::SeqCst);
                let r = lie(sh, n, lock(&sh.ctl).command_line(&mut sess, &cmd));
                rest = p::frame_reply(&r);
                take_chunk(&mut rest)
            }
            p::GETBUFFER => {
                if rest.is_empty() {
                    vec![0]
                } else {
                    take_chunk(&mut rest)
                }
            }
            p::SENDLINE => {
                let cmd = text_of(&payload);
                let r = lock(&sh.ctl).command_line(&mut sess, &cmd);
                // A client that never fetches must not grow this without
                // bound: keep the newest text.
                if line_out.len() > LINE_OUT_MAX {
                    line_out.clear();
                }
                line_out.extend_from_slice(&p::frame_reply(&r));
                vec![0x40]
            }
            p::GETLINE => {
                if line_out.is_empty() {
                    vec![0]
                } else {
                    let n = line_out.len().min(p::REPLY_CHUNK);
                    line_out.drain(..n).collect()
                }
            }
            p::READREADY => vec![u8::from(!line_out.is_empty()), 0],
            p::FLUSH => {
                line_out.clear();
                rest.clear();
                vec![0x40]
            }
            p::CTRL_RESPONSE => {
                let r = lock(&sh.ctl).control(p::ctrl_char(h.value));
                rest = p::frame_reply(&r);
                take_chunk(&mut rest)
            }
            p::WRITEBUFFER => {
                let mut ctl = lock(&sh.ctl);
                let mut status = None;
                let body = payload.strip_suffix(&[0]).unwrap_or(&payload);
                for (i, l) in body.split(|&c| c == 0).enumerate() {
                    let line = String::from_utf8_lossy(l);
                    if let Err(e) = ctl.command_line(&mut sess, &line) {
                        status = Some((u16::try_from(i).unwrap_or(u16::MAX), e));
                        break;
                    }
                }
                p::writebuffer_status(status).to_vec()
            }
            _ => p::frame_reply(&Err(3)),
        };
        conn.write_all(&reply)?;
    }
}

/// The command text of a payload: up to the first NUL or CR.
fn text_of(payload: &[u8]) -> String {
    let end = payload
        .iter()
        .position(|&c| c == 0 || c == b'\r')
        .unwrap_or(payload.len());
    String::from_utf8_lossy(&payload[..end]).into_owned()
}

fn take_chunk(rest: &mut Vec<u8>) -> Vec<u8> {
    let n = rest.len().min(p::REPLY_CHUNK);
    rest.drain(..n).collect()
}
