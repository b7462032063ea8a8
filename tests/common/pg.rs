//! A real PostgreSQL server for the tests, started by the test itself: `initdb` and
//! `pg_ctl` into a temporary folder, listening on a Unix socket in that folder only (no TCP),
//! on a random port number (the socket's name), stopped when dropped. The binaries come from
//! `pg_config --bindir`, else the newest `/usr/lib/postgresql/*/bin`; without them the test
//! fails (scripts/test installs the Debian package `postgresql`). `initdb` refuses to run as
//! root, so as root the server runs as `nobody` (through `runuser`).

use std::path::{Path, PathBuf};
use std::process::Command;

pub struct PgServer {
    pub dir: tempfile::TempDir,
    pub port: u16,
    bin: PathBuf,
    as_nobody: bool,
    /// Extra `-c` settings of the server (after the defaults).
    settings: String,
}

fn bindir() -> PathBuf {
    if let Ok(out) = Command::new("pg_config").arg("--bindir").output()
        && out.status.success()
    {
        let dir = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
        if dir.join("initdb").is_file() {
            return dir;
        }
    }
    let mut found: Vec<PathBuf> = std::fs::read_dir("/usr/lib/postgresql")
        .map(|d| d.flatten().map(|e| e.path().join("bin")).collect())
        .unwrap_or_default();
    found.retain(|p| p.join("initdb").is_file() && p.join("pg_ctl").is_file());
    found.sort_by_key(|p| {
        p.parent()
            .and_then(|v| v.file_name())
            .and_then(|v| v.to_str())
            .and_then(|v| v.parse::<u32>().ok())
            .unwrap_or(0)
    });
    found.pop().unwrap_or_else(|| {
        panic!(
            "PostgreSQL server binaries not found (pg_config --bindir, /usr/lib/postgresql/*/bin): \
             install the Debian package `postgresql` (scripts/test does)"
        )
    })
}

fn free_port() -> u16 {
    // A port nobody listens on now; the server uses it only to name its socket.
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

impl PgServer {
    /// A server for correctness tests: `fsync=off` (a crash of the test machine loses
    /// nothing the tests need).
    pub fn start() -> PgServer {
        PgServer::start_with("-c fsync=off")
    }

    /// A server as in production (`fsync` and `synchronous_commit` on) with
    /// `pg_stat_statements` loaded, for the figures.
    pub fn start_durable() -> PgServer {
        PgServer::start_with("-c shared_preload_libraries=pg_stat_statements")
    }

    fn start_with(settings: &str) -> PgServer {
        let bin = bindir();
        let dir = tempfile::Builder::new()
            .prefix("pg")
            .tempdir_in("/tmp")
            .unwrap();
        let as_nobody = unsafe { libc::geteuid() } == 0;
        let data = dir.path().join("data");
        std::fs::create_dir(&data).unwrap();
        if as_nobody {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o777)).unwrap();
            std::os::unix::fs::chown(&data, Some(65534), Some(65534)).unwrap();
        }
        let server = PgServer {
            port: free_port(),
            dir,
            bin,
            as_nobody,
            settings: settings.to_string(),
        };
        server.run(
            "initdb",
            &[
                "-D",
                data.to_str().unwrap(),
                "-A",
                "trust",
                "-U",
                "scanmill",
                "-E",
                "UTF8",
                "--no-sync",
            ],
        );
        server.ctl_start();
        server
    }

    fn command(&self, tool: &str) -> Command {
        let exe = self.bin.join(tool);
        if self.as_nobody {
            let mut c = Command::new("runuser");
            c.args(["-u", "nobody", "--"]).arg(exe);
            c
        } else {
            Command::new(exe)
        }
    }

    fn run(&self, tool: &str, args: &[&str]) {
        let out = self.command(tool).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{tool} {args:?}: {}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }

    fn data(&self) -> PathBuf {
        self.dir.path().join("data")
    }

    fn ctl_start(&self) {
        let opts = format!(
            "-k {} -p {} -c listen_addresses='' -c max_connections=60 {}",
            self.dir.path().display(),
            self.port,
            self.settings
        );
        let log = self.dir.path().join("server.log");
        self.run(
            "pg_ctl",
            &[
                "-D",
                self.data().to_str().unwrap(),
                "-o",
                &opts,
                "-l",
                log.to_str().unwrap(),
                "-w",
                "start",
            ],
        );
    }

    /// Stops the server (fast: connections are cut) and starts it again.
    pub fn restart(&self) {
        self.stop("fast");
        self.ctl_start();
    }

    pub fn stop(&self, mode: &str) {
        self.run(
            "pg_ctl",
            &[
                "-D",
                self.data().to_str().unwrap(),
                "-m",
                mode,
                "-w",
                "stop",
            ],
        );
    }

    pub fn socket_dir(&self) -> &Path {
        self.dir.path()
    }

    /// The URL of a database (`createdb` first for another than `postgres`).
    pub fn url(&self, db: &str) -> String {
        let host: String = self.socket_dir().to_str().unwrap().replace('/', "%2F");
        format!("postgres://scanmill@{host}:{}/{db}", self.port)
    }

    pub fn createdb(&self, name: &str) -> String {
        let mut c = postgres::Client::connect(&self.url("postgres"), postgres::NoTls).unwrap();
        c.batch_execute(&format!("CREATE DATABASE {name}")).unwrap();
        self.url(name)
    }

    pub fn client(&self, db: &str) -> postgres::Client {
        postgres::Client::connect(&self.url(db), postgres::NoTls).unwrap()
    }
}

impl Drop for PgServer {
    fn drop(&mut self) {
        let _ = self
            .command("pg_ctl")
            .args([
                "-D",
                self.data().to_str().unwrap(),
                "-m",
                "immediate",
                "stop",
            ])
            .output();
    }
}
