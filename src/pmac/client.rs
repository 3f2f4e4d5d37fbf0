//! A blocking client for a Turbo PMAC (or the emulator): the Ethernet
//! protocol with WRITEBUFFER downloads, or plain line-per-command TCP.
//! Every read and write has a timeout; no call blocks for ever.

use crate::pmac::protocol::{self as p, ProtocolError, Reply};
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};
use thiserror::Error;

/// How commands travel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transport {
    /// Ethernet protocol (port 1025), WRITEBUFFER for downloads.
    Ethernet,
    /// Ethernet protocol, but downloads line by line with GETRESPONSE (how
    /// dls-pmaclib downloads; the benchmark's baseline).
    EthernetLines,
    /// Plain text lines ended by CR, replies framed as with I3=2.
    Line,
}

/// Why a command or download failed: the link ([`ClientError::is_link`])
/// or the controller's refusal.
#[derive(Debug, Error)]
pub enum ClientError {
    /// The host did not resolve or refused the connection.
    #[error("cannot connect to {addr}: {source}")]
    Connect {
        /// The host as given (`host:port`).
        addr: String,
        /// The resolver's or the socket's error.
        source: io::Error,
    },
    /// A read or write on an open connection failed, or the controller
    /// closed it.
    #[error("connection lost: {0}")]
    Io(#[from] io::Error),
    /// No complete reply came within the client's timeout.
    #[error("no reply within {0:?}")]
    Timeout(Duration),
    /// The controller answered `ERRnnn` (the Turbo PMAC manual lists the
    /// numbers: 3 unrecognised command, 6 no room, ...).
    #[error("controller answered ERR{code:03} to '{cmd}'")]
    Pmac {
        /// The ERR number.
        code: u16,
        /// The command it refused.
        cmd: String,
    },
    /// A command that cannot be sent, or an answer that does not frame.
    #[error("{0}")]
    Protocol(#[from] ProtocolError),
}

impl ClientError {
    /// The link itself failed (as opposed to a controller error): a
    /// reconnect may help.
    pub fn is_link(&self) -> bool {
        matches!(
            self,
            ClientError::Io(_) | ClientError::Timeout(_) | ClientError::Protocol(_)
        )
    }
}

/// One connection to a controller, with the transport and timeout it was
/// opened with; replies are read whole before the next request goes out.
pub struct Client {
    stream: TcpStream,
    transport: Transport,
    timeout: Duration,
    addr: SocketAddr,
    /// Requests sent (for progress and the benchmark).
    pub requests: u64,
}

impl Client {
    /// Connect and set the reply format (I3=2 I6=1), checking the answer
    /// to `ver`.
    pub fn connect(host: &str, transport: Transport, timeout: Duration) -> Result<Client, ClientError> {
        let addr = host
            .to_socket_addrs()
            .map_err(|e| ClientError::Connect {
                addr: host.into(),
                source: e,
            })?
            .next()
            .ok_or_else(|| ClientError::Connect {
                addr: host.into(),
                source: io::Error::other("no address"),
            })?;
        let stream = TcpStream::connect_timeout(&addr, timeout).map_err(|e| ClientError::Connect {
            addr: host.into(),
            source: e,
        })?;
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(timeout))?;
        stream.set_write_timeout(Some(timeout))?;
        let mut c = Client {
            stream,
            transport,
            timeout,
            addr,
            requests: 0,
        };
        let v = c.command("I6=1 I3=2 VER")?;
        if v.first().is_none_or(|s| s.trim().parse::<f64>().is_err()) {
            return Err(ProtocolError::BadReply(format!("ver answered {v:?}")).into());
        }
        Ok(c)
    }

    /// A new connection to the same controller with the same settings.
    pub fn reconnect(&self) -> Result<Client, ClientError> {
        Client::connect(&self.addr.to_string(), self.transport, self.timeout)
    }

    /// How this client's commands travel.
    pub fn transport(&self) -> Transport {
        self.transport
    }

    /// Send one command line and return its data lines; an ERR reply is
    /// [`ClientError::Pmac`].
    pub fn command(&mut self, cmd: &str) -> Result<Vec<String>, ClientError> {
        self.requests += 1;
        let reply = match self.transport {
            Transport::Line => {
                if cmd.bytes().any(|c| c < 0x20) {
                    return Err(ProtocolError::BadChar.into());
                }
                let mut b = Vec::with_capacity(cmd.len() + 1);
                b.extend_from_slice(cmd.as_bytes());
                b.push(b'\r');
                self.stream.write_all(&b)?;
                self.read_reply(false)?
            }
            Transport::Ethernet | Transport::EthernetLines => {
                self.stream.write_all(&p::getresponse(cmd)?)?;
                self.read_reply(true)?
            }
        };
        match reply {
            Reply::Data(lines) => Ok(lines),
            Reply::Error(code) => Err(ClientError::Pmac { code, cmd: cmd.into() }),
        }
    }

    /// Read one framed reply, continuing with GETBUFFER after each full
    /// 1400-byte chunk on Ethernet.
    fn read_reply(&mut self, ethernet: bool) -> Result<Reply, ClientError> {
        let deadline = Instant::now() + self.timeout;
        let mut all = Vec::new();
        let mut chunk = 0usize;
        let mut buf = [0u8; 2048];
        loop {
            if let Some(r) = p::parse_reply(&all)? {
                return Ok(r);
            }
            if ethernet && chunk >= p::REPLY_CHUNK {
                self.stream
                    .write_all(&p::upload_request(p::GETBUFFER, p::REPLY_CHUNK as u16))?;
                chunk = 0;
            }
            if Instant::now() > deadline || all.len() > 1 << 20 {
                return Err(ClientError::Timeout(self.timeout));
            }
            let n = read_some(&mut self.stream, &mut buf, self.timeout)?;
            all.extend_from_slice(&buf[..n]);
            chunk += n;
        }
    }

    /// Download lines (into whatever buffer is open). Ethernet packs them
    /// into WRITEBUFFER packets and checks each status; the others send one
    /// line per request. On an ERR the error names the line (0-based index
    /// into `lines`); every line before it was stored.
    pub fn write_lines<S: AsRef<str>>(&mut self, lines: &[S]) -> Result<(), DownloadError> {
        match self.transport {
            Transport::Ethernet => {
                let packets = p::pack_lines(lines).map_err(|e| DownloadError {
                    stored: 0,
                    error: e.into(),
                })?;
                let mut base = 0usize;
                for pk in packets {
                    self.requests += 1;
                    let r = self.writebuffer(&pk.bytes);
                    match r {
                        Ok(None) => base += pk.lines,
                        Ok(Some((line, code))) => {
                            let at = base + usize::from(line).min(pk.lines.saturating_sub(1));
                            let cmd = lines.get(at).map_or("", |l| l.as_ref()).to_string();
                            return Err(DownloadError {
                                stored: at,
                                error: ClientError::Pmac { code, cmd },
                            });
                        }
                        Err(e) => return Err(DownloadError { stored: base, error: e }),
                    }
                }
                Ok(())
            }
            Transport::EthernetLines | Transport::Line => {
                for (i, l) in lines.iter().enumerate() {
                    self.command(l.as_ref())
                        .map_err(|e| DownloadError { stored: i, error: e })?;
                }
                Ok(())
            }
        }
    }

    fn writebuffer(&mut self, bytes: &[u8]) -> Result<Option<(u16, u16)>, ClientError> {
        self.stream.write_all(bytes)?;
        let mut st = [0u8; 4];
        let mut got = 0;
        let deadline = Instant::now() + self.timeout;
        while got < 4 {
            if Instant::now() > deadline {
                return Err(ClientError::Timeout(self.timeout));
            }
            got += read_some(&mut self.stream, &mut st[got..], self.timeout)?;
        }
        Ok(p::parse_writebuffer_status(&st)?)
    }
}

/// A failed download: how many lines were stored before the failure.
#[derive(Debug, Error)]
#[error("{error} (after {stored} lines were stored)")]
pub struct DownloadError {
    /// Lines of the download the controller took (all before the failing
    /// one); a retry starts after them.
    pub stored: usize,
    /// What failed.
    #[source]
    pub error: ClientError,
}

fn read_some(s: &mut TcpStream, buf: &mut [u8], timeout: Duration) -> Result<usize, ClientError> {
    match s.read(buf) {
        Ok(0) => Err(io::Error::new(io::ErrorKind::UnexpectedEof, "controller closed the connection").into()),
        Ok(n) => Ok(n),
        Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
            Err(ClientError::Timeout(timeout))
        }
        Err(e) => Err(e.into()),
    }
}
