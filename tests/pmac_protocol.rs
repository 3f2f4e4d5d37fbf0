//! The emulator's Ethernet protocol byte for byte, over TCP on 127.0.0.1,
//! as a client that is not ours would see it. Every read has a timeout.

use microcam::pmac::controller::{Clock, Config, Emulator};
use microcam::pmac::protocol::{self as p, Header};
use microcam::pmac::server::{Faults, Server};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

fn server() -> Server {
    let ctl = Emulator::new(Config::default(), Clock::scaled(1000.0), None);
    Server::start("127.0.0.1:0".parse().unwrap(), ctl, Faults::default()).unwrap()
}

fn connect(s: &Server) -> TcpStream {
    let c = TcpStream::connect(s.addr()).unwrap();
    c.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    c
}

/// One recv, as dls-pmaclib does: the whole reply must come in it.
fn recv(c: &mut TcpStream) -> Vec<u8> {
    let mut b = vec![0u8; 4096];
    let n = c.read(&mut b).unwrap();
    b.truncate(n);
    b
}

fn ask(c: &mut TcpStream, cmd: &str) -> Vec<u8> {
    c.write_all(&p::getresponse(cmd).unwrap()).unwrap();
    recv(c)
}

#[test]
fn getresponse_framing() {
    let s = server();
    let mut c = connect(&s);
    assert_eq!(ask(&mut c, "i6=1 i3=2 ver"), b"1.945  \r\x06");
    assert_eq!(ask(&mut c, "cid"), b"603382\r\x06");
    assert_eq!(ask(&mut c, "P1=5"), b"\x06");
    assert_eq!(ask(&mut c, "P1 P2"), b"5\r0\r\x06");
    assert_eq!(ask(&mut c, "NONSENSE"), b"\x07ERR003\r");
    assert_eq!(ask(&mut c, "&1R"), b"\x07ERR015\r");
}

#[test]
fn long_reply_continues_with_getbuffer() {
    let s = server();
    let mut c = connect(&s);
    let cmd = format!("&1{}", " ??".repeat(100));
    let first = ask(&mut c, &cmd);
    assert_eq!(first.len(), p::REPLY_CHUNK);
    c.write_all(&p::upload_request(p::GETBUFFER, 1400)).unwrap();
    let rest = recv(&mut c);
    assert_eq!(first.len() + rest.len(), 100 * 19 + 1);
    assert_eq!(*rest.last().unwrap(), p::ACK);
}

#[test]
fn sendline_getline_readready_flush() {
    let s = server();
    let mut c = connect(&s);
    let mut req = Header::new(p::VR_DOWNLOAD, p::SENDLINE, 3).encode().to_vec();
    req.extend_from_slice(b"cid");
    c.write_all(&req).unwrap();
    assert_eq!(recv(&mut c), [0x40]);
    c.write_all(&p::upload_request(p::READREADY, 2)).unwrap();
    assert_eq!(recv(&mut c), [1, 0]);
    c.write_all(&p::upload_request(p::GETLINE, 1400)).unwrap();
    assert_eq!(recv(&mut c), b"603382\r\x06");
    c.write_all(&p::upload_request(p::READREADY, 2)).unwrap();
    assert_eq!(recv(&mut c), [0, 0]);
    c.write_all(&p::upload_request(p::FLUSH, 0)).unwrap();
    assert_eq!(recv(&mut c), [0x40]);
}

#[test]
fn ctrl_response_accepts_both_byte_orders() {
    let s = server();
    let mut c = connect(&s);
    c.write_all(&p::ctrl_response(0x07)).unwrap();
    let a = recv(&mut c);
    let mut h = Header::new(p::VR_UPLOAD, p::CTRL_RESPONSE, 1400);
    h.value = 0x0700;
    c.write_all(&h.encode()).unwrap();
    let b = recv(&mut c);
    assert_eq!(a, b);
    assert_eq!(*a.last().unwrap(), p::ACK);
}

#[test]
fn writebuffer_status_names_the_failing_line() {
    let s = server();
    let mut c = connect(&s);
    assert_eq!(ask(&mut c, "OPEN PROG 1 CLEAR"), b"\x06");
    let pk = p::pack_lines(&["LINEAR X1 F1", "X2", "OPEN PROG 2", "X3"]).unwrap();
    assert_eq!(pk.len(), 1);
    c.write_all(&pk[0].bytes).unwrap();
    let st = recv(&mut c);
    // Line 2 (0-based) is refused with ERR007; the two before it are stored.
    assert_eq!(p::parse_writebuffer_status(&st).unwrap(), Some((2, 7)));
    assert_eq!(ask(&mut c, "CLOSE"), b"\x06");
    let free_before = String::from_utf8(ask(&mut c, "SIZE")).unwrap();
    assert_eq!(free_before, format!("{}\r\x06", 65_536 - 3 - 2));
    let ok = p::pack_lines(&["CLOSE"]).unwrap();
    c.write_all(&ok[0].bytes).unwrap();
    assert_eq!(recv(&mut c), [0, 0, 0, 0]);
}

#[test]
fn garbage_never_stops_the_server() {
    let s = server();
    for seed in 0..40u32 {
        let mut c = connect(&s);
        let junk: Vec<u8> = (0..(seed * 37 % 300))
            .map(|k| (seed.wrapping_mul(2654435761).wrapping_add(k.wrapping_mul(40503)) >> 7) as u8)
            .collect();
        let _ = c.write_all(&junk);
        let _ = c.shutdown(std::net::Shutdown::Write);
        let mut sink = Vec::new();
        let _ = c.read_to_end(&mut sink);
    }
    // Still answering, byte for byte.
    let mut c = connect(&s);
    assert_eq!(ask(&mut c, "cid"), b"603382\r\x06");
}

#[test]
fn plain_text_lines_on_the_same_port() {
    let s = server();
    let mut c = connect(&s);
    c.write_all(b"cid\rP5=2 P5\r").unwrap();
    let mut got = Vec::new();
    while got.iter().filter(|&&b| b == p::ACK).count() < 2 {
        got.extend(recv(&mut c));
    }
    assert_eq!(got, b"603382\r\x062\r\x06");
}

/// `Faults::reset_mid_run_from`: no reset while nothing runs, however many
/// requests pass; one reset at the first request that finds a program
/// running; none after. The clock is set by hand, so the program is
/// running (its one move takes 600 s) exactly when the test says.
#[test]
fn mid_run_reset_waits_for_a_running_program_and_fires_once() {
    let ctl = Emulator::new(Config::default(), Clock::Manual(0.0), None);
    let faults = Faults {
        reset_mid_run_from: Some(2),
        ..Faults::default()
    };
    let s = Server::start("127.0.0.1:0".parse().unwrap(), ctl, faults).unwrap();
    let mut c = connect(&s);
    let running = |s: &Server| s.controller.lock().unwrap().running();
    let download = |c: &mut TcpStream| {
        for cmd in ["OPEN PROG 1 CLEAR", "LINEAR X10 F1", "CLOSE"] {
            assert_eq!(ask(c, cmd), b"\x06", "{cmd}");
        }
    };
    download(&mut c);
    assert_eq!(ask(&mut c, "P1=5"), b"\x06");
    assert_eq!(ask(&mut c, "P1"), b"5\r\x06");
    assert!(!running(&s));
    // The request that starts the run finds nothing running: no reset.
    assert_eq!(ask(&mut c, "&1B1R"), b"\x06");
    assert!(running(&s));
    // The next one finds it running: the controller resets (and forgets
    // its programs, as a reset does).
    ask(&mut c, "P1");
    assert!(!running(&s), "no reset mid-run");
    assert_eq!(ask(&mut c, "&1B1R"), b"\x07ERR015\r");
    // Once only: a second run is left alone.
    download(&mut c);
    assert_eq!(ask(&mut c, "&1B1R"), b"\x06");
    for _ in 0..3 {
        ask(&mut c, "P1");
        assert!(running(&s), "a second reset");
    }
}
