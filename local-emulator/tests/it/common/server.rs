//! `hort serve` over loopback, as a client sees it: the binary on a free port with a temporary
//! data folder, spoken to in plain HTTP/1.1 over a `TcpStream`. Shared by `serve.rs` and
//! `serve_load.rs`.

use super::HORT;
use serde_json::{Value, json};
use std::io::{BufRead, BufReader, ErrorKind, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

pub fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

/// The bundled Cornell box as inline files.
pub fn cornell() -> Value {
    let file = |name: &str| std::fs::read_to_string(scenes().join("cornell").join(name)).unwrap();
    json!({
        "main": "cornell.json",
        "files": {
            "cornell.json": file("cornell.json"),
            "cornell.obj": file("cornell.obj"),
            "cornell.mtl": file("cornell.mtl"),
        }
    })
}

/// A running `hort serve`; stopped with SIGTERM on drop.
pub struct Serve {
    pub child: Child,
    pub port: u16,
    pub log: Arc<Mutex<String>>,
}

impl Serve {
    pub fn start(data: &Path) -> Serve {
        Serve::start_with(data, &[])
    }

    pub fn start_with(data: &Path, extra: &[&str]) -> Serve {
        let mut child = Command::new(HORT)
            .args(["serve", "--port", "0", "--workers", "2", "--data-dir"])
            .arg(data)
            .args(extra)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("hort serve starts");
        let stderr = child.stderr.take().unwrap();
        let log = Arc::new(Mutex::new(String::new()));
        let (tx, rx) = mpsc::channel();
        let sink = Arc::clone(&log);
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                // Logged before the port is sent, so a test that has the port sees the line.
                {
                    let mut log = sink.lock().unwrap_or_else(|e| e.into_inner());
                    log.push_str(&line);
                    log.push('\n');
                }
                if let Some(rest) = line.split("listening on http://127.0.0.1:").nth(1) {
                    let port: String = rest.chars().take_while(char::is_ascii_digit).collect();
                    let _ = tx.send(port.parse::<u16>().unwrap());
                }
            }
        });
        let port = match rx.recv_timeout(Duration::from_secs(60)) {
            Ok(port) => port,
            Err(_) => panic!(
                "hort serve did not say where it listens: {}",
                log.lock().unwrap()
            ),
        };
        Serve { child, port, log }
    }

    /// Ends the server as a crash would (SIGKILL): nothing is saved on the way out.
    pub fn kill_hard(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    pub fn call(&self, method: &str, path: &str, headers: &[(&str, &str)], body: &[u8]) -> Reply {
        call(self.port, method, path, headers, body)
    }

    pub fn post(&self, path: &str, body: &Value, headers: &[(&str, &str)]) -> Reply {
        let mut all = vec![("Content-Type", "application/json")];
        all.extend_from_slice(headers);
        self.call("POST", path, &all, body.to_string().as_bytes())
    }

    pub fn get(&self, path: &str) -> Reply {
        self.call("GET", path, &[], b"")
    }

    /// Polls the job until it ends; panics with the server's log if it takes too long.
    pub fn wait_done(&self, job: &str, limit: Duration) -> Value {
        let t0 = Instant::now();
        loop {
            let status = self.get(&format!("/renders/{job}")).json();
            match status["status"].as_str().unwrap() {
                "QUEUED" | "RUNNING" => {}
                _ => return status,
            }
            assert!(
                t0.elapsed() < limit,
                "job {job} still {status} after {limit:?}; server log:\n{}",
                self.log.lock().unwrap()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        if let Ok(Some(_)) = self.child.try_wait() {
            return;
        }
        let _ = Command::new("kill")
            .arg(self.child.id().to_string())
            .status();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(15) {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One HTTP response.
pub struct Reply {
    pub status: u16,
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
}

impl Reply {
    pub fn json(&self) -> Value {
        serde_json::from_slice(&self.body).unwrap_or_else(|e| {
            panic!(
                "not JSON ({e}): {} {}",
                self.status,
                String::from_utf8_lossy(&self.body)
            )
        })
    }

    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }

    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }

    /// (code, message, field) of an error answer.
    pub fn error(&self) -> (String, String, Option<String>) {
        let v = self.json();
        let e = &v["error"];
        (
            e["code"]
                .as_str()
                .unwrap_or_else(|| panic!("{v}"))
                .to_owned(),
            e["message"].as_str().unwrap().to_owned(),
            e["field"].as_str().map(str::to_owned),
        )
    }
}

/// Sends one request (`Content-Length` added unless it or `Transfer-Encoding` is given) and
/// reads the whole answer.
pub fn call(port: u16, method: &str, path: &str, headers: &[(&str, &str)], body: &[u8]) -> Reply {
    let mut stream = TcpStream::connect(("127.0.0.1", port)).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(120)))
        .unwrap();
    // As browsers and curl send it: the port included (presigned URLs sign it).
    let mut head =
        format!("{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n");
    for (k, v) in headers {
        head += &format!("{k}: {v}\r\n");
    }
    if !headers.iter().any(|(k, _)| {
        k.eq_ignore_ascii_case("content-length") || k.eq_ignore_ascii_case("transfer-encoding")
    }) {
        head += &format!("Content-Length: {}\r\n", body.len());
    }
    head += "\r\n";
    // A server that refuses a body answers and closes without reading the rest of it (a body
    // over the limit is read no further than the limit): the rest of the body then cannot be sent
    // (the connection is reset), but the answer came first and is read below, as curl does. How
    // far the write gets depends on how fast the server reads, so it is not the test's outcome.
    if let Err(e) = stream
        .write_all(head.as_bytes())
        .and_then(|()| stream.write_all(body))
    {
        assert!(
            matches!(e.kind(), ErrorKind::BrokenPipe | ErrorKind::ConnectionReset),
            "{method} {path}: {e}"
        );
    }
    let mut raw = Vec::new();
    // After a reset the answer received before it is still read, then the reset is reported.
    if let Err(e) = stream.read_to_end(&mut raw) {
        assert!(
            e.kind() == ErrorKind::ConnectionReset && !raw.is_empty(),
            "{method} {path}: {e} after {} bytes of the answer",
            raw.len()
        );
    }
    let end = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("no HTTP head in {:?}", String::from_utf8_lossy(&raw)));
    let head = String::from_utf8_lossy(&raw[..end]).into_owned();
    let mut lines = head.split("\r\n");
    let status = lines
        .next()
        .unwrap()
        .split(' ')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_owned(), v.trim().to_owned()))
        .collect();
    Reply {
        status,
        headers,
        body: raw[end + 4..].to_vec(),
    }
}
