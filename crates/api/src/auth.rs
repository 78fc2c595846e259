//! Users, roles, sessions, the control lease and the log-in rate limit.
//!
//! Users live in a TOML file (`[[user]] name, role, hash`, argon2id PHC strings), written
//! atomically. Sessions are random bearer tokens kept in memory; they expire. Passwords and
//! tokens are never logged.

use std::collections::HashMap;
use std::net::IpAddr;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use argon2::password_hash::{PasswordHash, PasswordHasher, PasswordVerifier, SaltString};
use argon2::{Algorithm, Argon2, Params, Version};
use axum::http::StatusCode;
use serde::{Deserialize, Serialize};

use crate::problem::Problem;

/// Roles, each allowed what the ones below it are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Reads everything.
    Viewer,
    /// Controls the machine (with the lease).
    Operator,
    /// Writes the setup (tool table, offsets, PLC forces).
    Setter,
    /// Takes the lease over.
    Admin,
}

impl Role {
    /// Lower-case name.
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Viewer => "viewer",
            Role::Operator => "operator",
            Role::Setter => "setter",
            Role::Admin => "admin",
        }
    }

    /// The role of a name.
    pub fn parse(name: &str) -> Option<Role> {
        match name {
            "viewer" => Some(Role::Viewer),
            "operator" => Some(Role::Operator),
            "setter" => Some(Role::Setter),
            "admin" => Some(Role::Admin),
            _ => None,
        }
    }
}

/// One user in the file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct User {
    /// Name.
    pub name: String,
    /// Role.
    pub role: Role,
    /// argon2id PHC string.
    pub hash: String,
    /// The password is a one-time password (the first admin's).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub must_change: bool,
}

#[derive(Debug, Default, Serialize, Deserialize)]
struct UsersFile {
    #[serde(default)]
    user: Vec<User>,
}

fn argon2() -> Argon2<'static> {
    // OWASP's argon2id minimum: 19 MiB, 2 passes, 1 lane.
    let params = Params::new(19 * 1024, 2, 1, None).unwrap_or_default();
    Argon2::new(Algorithm::Argon2id, Version::V0x13, params)
}

/// Random bytes from the operating system.
pub fn random_bytes<const N: usize>() -> [u8; N] {
    let mut b = [0u8; N];
    getrandom::fill(&mut b).expect("the operating system's random source");
    b
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The argon2id hash of a password.
pub fn hash_password(password: &str) -> anyhow::Result<String> {
    let salt =
        SaltString::encode_b64(&random_bytes::<16>()).map_err(|e| anyhow::anyhow!("salt: {e}"))?;
    Ok(argon2()
        .hash_password(password.as_bytes(), &salt)
        .map_err(|e| anyhow::anyhow!("hashing: {e}"))?
        .to_string())
}

fn verify(password: &str, hash: &str) -> bool {
    PasswordHash::new(hash).is_ok_and(|h| argon2().verify_password(password.as_bytes(), &h).is_ok())
}

/// Reads a users file.
pub fn load_users(path: &Path) -> anyhow::Result<Vec<User>> {
    let text = std::fs::read_to_string(path)?;
    let file: UsersFile =
        toml::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(file.user)
}

/// Writes a users file atomically (temporary file, fsync, rename, fsync of the folder),
/// readable by its owner only.
pub fn save_users(path: &Path, users: &[User]) -> anyhow::Result<()> {
    let text = toml::to_string(&UsersFile {
        user: users.to_vec(),
    })?;
    crate::files::write_atomically(path, text.as_bytes(), 0o600)
}

/// Adds or replaces a user in the file (`rtcnc user add`).
pub fn add_user(path: &Path, name: &str, role: Role, password: &str) -> anyhow::Result<()> {
    if !valid_name(name) {
        anyhow::bail!("user name: letters, digits, '.', '_' and '-', at most 32");
    }
    if password.chars().count() < 8 {
        anyhow::bail!("the password needs at least 8 characters");
    }
    let mut users = if path.exists() {
        load_users(path)?
    } else {
        Vec::new()
    };
    users.retain(|u| u.name != name);
    users.push(User {
        name: name.to_string(),
        role,
        hash: hash_password(password)?,
        must_change: false,
    });
    save_users(path, &users)
}

fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 32
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b))
}

/// A random password of 16 letters and digits.
pub fn random_password() -> String {
    const ALPHABET: &[u8] = b"abcdefghijkmnopqrstuvwxyzABCDEFGHJKLMNPQRSTUVWXYZ23456789";
    random_bytes::<16>()
        .iter()
        .map(|b| ALPHABET[usize::from(*b) % ALPHABET.len()] as char)
        .collect()
}

/// A logged-in session.
#[derive(Debug, Clone)]
pub struct Session {
    /// Its id (not the token).
    pub id: u64,
    /// User.
    pub user: String,
    /// Role.
    pub role: Role,
    /// When it ends.
    pub expires: Instant,
    /// Must change the password first.
    pub must_change: bool,
}

impl Session {
    /// 403 unless the role is at least `role` (and the one-time password was changed).
    pub fn require(&self, role: Role) -> Result<(), Problem> {
        if self.must_change {
            return Err(Problem::new(
                StatusCode::FORBIDDEN,
                "auth.password_change_required",
                "change the one-time password first (POST /api/session/password)",
            ));
        }
        if self.role < role {
            return Err(Problem::new(
                StatusCode::FORBIDDEN,
                "auth.forbidden",
                format!(
                    "this needs the role {} or above; {} is {}",
                    role.as_str(),
                    self.user,
                    self.role.as_str()
                ),
            ));
        }
        Ok(())
    }
}

/// The control lease: one operator session at a time.
#[derive(Debug, Clone)]
pub struct LeaseHolder {
    /// Session id.
    pub session: u64,
    /// User.
    pub user: String,
}

/// Users, sessions, lease, rate limit.
pub struct Auth {
    users_file: PathBuf,
    users: Mutex<Vec<User>>,
    sessions: Mutex<HashMap<String, Session>>,
    next_id: Mutex<u64>,
    ttl: Duration,
    lease: Mutex<Option<LeaseHolder>>,
    failures: Mutex<HashMap<IpAddr, (u32, Instant)>>,
    /// Verified against for unknown users, so the answer's time does not tell which exist.
    dummy_hash: String,
}

/// Failed log-ins allowed per address per minute.
const FAILURES_PER_MINUTE: u32 = 5;

impl Auth {
    /// Reads the users file; with none, creates it with an `admin` whose one-time password
    /// is returned (to be printed once).
    pub fn open(users_file: &Path, ttl: Duration) -> anyhow::Result<(Auth, Option<String>)> {
        let mut first = None;
        let users = if users_file.exists() {
            load_users(users_file)?
        } else {
            let password = random_password();
            let users = vec![User {
                name: "admin".into(),
                role: Role::Admin,
                hash: hash_password(&password)?,
                must_change: true,
            }];
            save_users(users_file, &users)?;
            first = Some(password);
            users
        };
        Ok((
            Auth {
                users_file: users_file.to_path_buf(),
                users: Mutex::new(users),
                sessions: Mutex::new(HashMap::new()),
                next_id: Mutex::new(1),
                ttl,
                lease: Mutex::new(None),
                failures: Mutex::new(HashMap::new()),
                dummy_hash: hash_password(&random_password())?,
            },
            first,
        ))
    }

    /// The user whose password this is, for surfaces with log-ins of their own (OPC UA):
    /// no session is made. An unknown user costs the same time as a wrong password.
    pub fn verify_password(&self, user: &str, password: &str) -> Option<User> {
        let found = {
            let users = self.users.lock().unwrap_or_else(|e| e.into_inner());
            users.iter().find(|u| u.name == user).cloned()
        };
        match found {
            Some(u) => verify(password, &u.hash).then_some(u),
            None => {
                let _ = verify(password, &self.dummy_hash);
                None
            }
        }
    }

    /// Session lifetime.
    pub fn ttl(&self) -> Duration {
        self.ttl
    }

    /// Logs in; returns the token and the session.
    pub fn login(
        &self,
        from: IpAddr,
        user: &str,
        password: &str,
    ) -> Result<(String, Session), Problem> {
        {
            let mut f = self.failures.lock().unwrap_or_else(|e| e.into_inner());
            if let Some((n, since)) = f.get(&from).copied() {
                if since.elapsed() > Duration::from_secs(60) {
                    f.remove(&from);
                } else if n >= FAILURES_PER_MINUTE {
                    let wait = 60u64.saturating_sub(since.elapsed().as_secs()).max(1);
                    return Err(Problem::new(
                        StatusCode::TOO_MANY_REQUESTS,
                        "auth.rate_limited",
                        format!("too many failed log-ins from this address; wait {wait} s"),
                    )
                    .retry_after(wait));
                }
            }
        }
        let found = {
            let users = self.users.lock().unwrap_or_else(|e| e.into_inner());
            users.iter().find(|u| u.name == user).cloned()
        };
        let ok = match &found {
            Some(u) => verify(password, &u.hash),
            None => {
                let _ = verify(password, &self.dummy_hash);
                false
            }
        };
        let Some(u) = found.filter(|_| ok) else {
            let mut f = self.failures.lock().unwrap_or_else(|e| e.into_inner());
            let e = f.entry(from).or_insert((0, Instant::now()));
            e.0 += 1;
            return Err(Problem::new(
                StatusCode::UNAUTHORIZED,
                "auth.bad_credentials",
                "wrong user name or password",
            ));
        };
        let token = hex(&random_bytes::<32>());
        let id = {
            let mut n = self.next_id.lock().unwrap_or_else(|e| e.into_inner());
            *n += 1;
            *n
        };
        let session = Session {
            id,
            user: u.name.clone(),
            role: u.role,
            expires: Instant::now() + self.ttl,
            must_change: u.must_change,
        };
        let mut s = self.sessions.lock().unwrap_or_else(|e| e.into_inner());
        s.retain(|_, v| v.expires > Instant::now());
        s.insert(token.clone(), session.clone());
        Ok((token, session))
    }

    /// The live session of a token, or 401.
    pub fn session(&self, token: Option<&str>) -> Result<Session, Problem> {
        let unauthorized = |detail: &str| {
            Problem::new(
                StatusCode::UNAUTHORIZED,
                "auth.unauthorized",
                detail.to_string(),
            )
        };
        let token = token.ok_or_else(|| {
            unauthorized("log in first (POST /api/session) and send the token as a Bearer")
        })?;
        let mut s = self.sessions.lock().unwrap_or_else(|e| e.into_inner());
        match s.get(token) {
            Some(session) if session.expires > Instant::now() => Ok(session.clone()),
            Some(_) => {
                let id = s.remove(token).map(|x| x.id);
                drop(s);
                if let Some(id) = id {
                    self.release_if_held(id);
                }
                Err(Problem::new(
                    StatusCode::UNAUTHORIZED,
                    "auth.expired",
                    "the session has expired; log in again",
                ))
            }
            None => Err(unauthorized("unknown or ended session")),
        }
    }

    /// Ends a session (and its lease).
    pub fn logout(&self, token: &str) {
        let removed = self
            .sessions
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(token);
        if let Some(s) = removed {
            self.release_if_held(s.id);
        }
    }

    /// Changes the session user's password.
    pub fn change_password(&self, token: &str, old: &str, new: &str) -> Result<(), Problem> {
        let session = self.session(Some(token))?;
        if new.chars().count() < 8 {
            return Err(Problem::unprocessable(
                "auth.weak_password",
                "the new password needs at least 8 characters",
            ));
        }
        let mut users = self.users.lock().unwrap_or_else(|e| e.into_inner());
        let Some(u) = users.iter_mut().find(|u| u.name == session.user) else {
            return Err(Problem::new(
                StatusCode::UNAUTHORIZED,
                "auth.unauthorized",
                "no such user",
            ));
        };
        if !verify(old, &u.hash) {
            return Err(Problem::new(
                StatusCode::FORBIDDEN,
                "auth.bad_credentials",
                "the old password is wrong",
            ));
        }
        u.hash = hash_password(new).map_err(|e| Problem::internal(e.to_string()))?;
        u.must_change = false;
        save_users(&self.users_file, &users).map_err(|e| Problem::internal(e.to_string()))?;
        drop(users);
        let mut s = self.sessions.lock().unwrap_or_else(|e| e.into_inner());
        for v in s.values_mut().filter(|v| v.user == session.user) {
            v.must_change = false;
        }
        Ok(())
    }

    /// The lease holder.
    pub fn lease(&self) -> Option<LeaseHolder> {
        let mut lease = self.lease.lock().unwrap_or_else(|e| e.into_inner());
        // A lease whose session ended is free.
        if let Some(l) = lease.as_ref() {
            let live = self
                .sessions
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .values()
                .any(|s| s.id == l.session && s.expires > Instant::now());
            if !live {
                *lease = None;
            }
        }
        lease.clone()
    }

    /// Takes the lease (an admin may take it over from another session).
    pub fn acquire(&self, session: &Session, take_over: bool) -> Result<(), Problem> {
        session.require(Role::Operator)?;
        let current = self.lease();
        let mut lease = self.lease.lock().unwrap_or_else(|e| e.into_inner());
        match current {
            Some(l) if l.session != session.id => {
                if take_over {
                    session.require(Role::Admin)?;
                } else {
                    return Err(Problem::conflict(
                        "lease.held",
                        format!("{} holds the control lease", l.user),
                    )
                    .with_extra(serde_json::json!({ "holder": l.user })));
                }
            }
            _ => {}
        }
        *lease = Some(LeaseHolder {
            session: session.id,
            user: session.user.clone(),
        });
        Ok(())
    }

    /// Gives the lease back.
    pub fn release(&self, session: &Session) -> Result<(), Problem> {
        match self.lease() {
            Some(l) if l.session == session.id => {
                self.release_if_held(session.id);
                Ok(())
            }
            Some(l) => Err(Problem::conflict(
                "lease.not_holder",
                format!("{} holds the control lease, not this session", l.user),
            )),
            None => Ok(()),
        }
    }

    fn release_if_held(&self, id: u64) {
        let mut lease = self.lease.lock().unwrap_or_else(|e| e.into_inner());
        if lease.as_ref().is_some_and(|l| l.session == id) {
            *lease = None;
        }
    }

    /// 409 unless this session holds the lease (and is an operator).
    pub fn require_lease(&self, session: &Session) -> Result<(), Problem> {
        session.require(Role::Operator)?;
        match self.lease() {
            Some(l) if l.session == session.id => Ok(()),
            Some(l) => Err(Problem::conflict(
                "lease.held",
                format!("{} holds the control lease: watch, or ask an admin", l.user),
            )
            .with_extra(serde_json::json!({ "holder": l.user }))),
            None => Err(Problem::conflict(
                "lease.required",
                "take the control lease first (POST /api/lease)",
            )),
        }
    }

    /// Seconds left of a session.
    pub fn expires_in(&self, session: &Session) -> u64 {
        session
            .expires
            .saturating_duration_since(Instant::now())
            .as_secs()
    }
}
