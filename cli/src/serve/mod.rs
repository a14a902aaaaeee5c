//! `prism serve`: a live preview in the browser. The page shows the render
//! as it happens (a coarse pass, then tiles at full resolution, then the
//! full sample count), follows every save of the scene file and the files
//! it reads, shows a broken scene's errors with their lines, and explains
//! any pixel (`prism explain` in the page). A front end beside the CLI:
//! the library knows nothing of HTTP.
//!
//! Safe by default: it binds 127.0.0.1; a request whose Host header is not
//! a name of the address it serves is refused (421), against DNS
//! rebinding; requests marked cross-site are refused (403); it serves its
//! embedded page and the images it rendered, no file from disk. Work done
//! on request is bounded (`views`), and so are connections (`conn`).
//! Bound to another address (network mode), it also requires a random
//! token, given in the printed URL and kept in a cookie, as Jupyter does.

mod conn;
mod interfaces;
mod space;
mod views;
mod worker;

use std::convert::Infallible;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use axum::Router;
use axum::body::Body;
use axum::extract::{Query, Request, State};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use clap::Args;
use futures_util::stream::{self, StreamExt};
use serde::Deserialize;
use tokio::sync::Semaphore;
use tokio::sync::broadcast::error::RecvError;

use prism::text::{Shown, escape_controls};

use crate::args::{BAD_INPUT, LoadArgs};
use conn::{Connections, LocalAddr};
use interfaces::Interfaces;
use views::{Kind, Refused, Views};
use worker::Shared;

/// Event streams (open pages) served at once.
const MAX_CLIENTS: usize = 16;

#[derive(Args)]
pub struct ServeArgs {
    /// The scene file (TOML) to render and watch.
    scene: PathBuf,
    /// Port (0: any free port).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// Address to listen on; anything but a loopback address (127.0.0.1,
    /// ::1, ::ffff:127.0.0.1) exposes the preview to the network, behind a
    /// random token; 0.0.0.0 (or ::) listens on every interface.
    #[arg(long, default_value = "127.0.0.1")]
    bind: IpAddr,
    /// Also accept requests for this host name (repeatable; `*`: any),
    /// e.g. a DNS name of this machine or a reverse proxy's.
    #[arg(long = "allow-host", value_name = "NAME")]
    allow_host: Vec<String>,
    /// Also stream the tiles to the tev image viewer at HOST:PORT.
    #[arg(long, value_name = "HOST:PORT")]
    display_server: Option<String>,
    #[command(flatten)]
    load: LoadArgs,
}

/// Who may ask: the Host names served, and the token in network mode.
struct Access {
    /// Host names (lower case, no port) answered, besides the address a
    /// request came in on.
    hosts: Vec<String>,
    /// Addresses answered as IP literals, besides the one a request came
    /// in on: the bound one and those given with --allow-host.
    addresses: Vec<IpAddr>,
    /// Bound to every interface: the addresses of all of them.
    interfaces: Option<Interfaces>,
    any_host: bool,
    /// Network mode: the token, and the cookie that keeps it.
    token: Option<String>,
    cookie: String,
}

#[derive(Clone)]
struct App {
    shared: Arc<Shared>,
    views: Arc<Views>,
    access: Arc<Access>,
    connections: Arc<Connections>,
    clients: Arc<AtomicUsize>,
    explains: Arc<Semaphore>,
}

pub fn run(args: &ServeArgs) -> ExitCode {
    let options = match args.load.options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {}", escape_controls(&e));
            return ExitCode::from(BAD_INPUT);
        }
    };
    if !args.scene.is_file() {
        eprintln!("error: {}: no such scene file", Shown(args.scene.display()));
        return ExitCode::from(BAD_INPUT);
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        // Blocking work is bounded by the views' permits; this bounds threads.
        .max_blocking_threads(16)
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: cannot start the server: {e}");
            return ExitCode::FAILURE;
        }
    };
    runtime.block_on(serve(args, options))
}

/// A random token: 24 bytes from the operating system, in hex.
fn new_token() -> Result<String, String> {
    let mut bytes = [0u8; 24];
    getrandom::fill(&mut bytes).map_err(|e| e.to_string())?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// This machine's name, to accept it as a Host.
fn hostname() -> Option<String> {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|h| h.trim().to_ascii_lowercase())
        .filter(|h| !h.is_empty())
}

async fn serve(args: &ServeArgs, options: prism::scene::LoadOptions) -> ExitCode {
    let listener = match tokio::net::TcpListener::bind(SocketAddr::new(args.bind, args.port)).await
    {
        Ok(l) => l,
        Err(e) => {
            eprintln!("error: cannot listen on {}:{}: {e}", args.bind, args.port);
            return ExitCode::from(BAD_INPUT);
        }
    };
    let addr = match listener.local_addr() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    // ::ffff:127.0.0.1 is loopback, as 127.0.0.1 is.
    let ip = addr.ip().to_canonical();
    let network = !ip.is_loopback();
    let mut hosts: Vec<String> = args
        .allow_host
        .iter()
        .map(|h| {
            if h.trim() == "*" {
                "*".into()
            } else {
                host_name(h)
            }
        })
        .collect();
    if ip.is_loopback() || ip.is_unspecified() {
        hosts.push("localhost".into());
    }
    let mut addresses: Vec<IpAddr> = hosts
        .iter()
        .filter_map(|h| h.parse::<IpAddr>().ok())
        .map(|a| a.to_canonical())
        .collect();
    if !ip.is_unspecified() {
        addresses.push(ip);
    }
    // Bound to every interface: a client may type any of their addresses.
    let all = if ip.is_unspecified() {
        interfaces::addresses()
    } else {
        Vec::new()
    };
    let reachable = interfaces::urls_for(ip, &all);
    let name = hostname();
    if network {
        hosts.extend(name.clone());
    }
    let token = if network {
        match new_token() {
            Ok(t) => Some(t),
            Err(e) => {
                eprintln!("error: cannot make a token: {e}");
                return ExitCode::FAILURE;
            }
        }
    } else {
        None
    };
    let tev = match &args.display_server {
        None => None,
        Some(address) => match crate::tev::Tev::connect(address, &args.scene.display().to_string())
        {
            Ok(t) => Some(t),
            Err(e) => {
                eprintln!("error: {}", escape_controls(&e));
                return ExitCode::from(BAD_INPUT);
            }
        },
    };
    let shared = Shared::new(args.scene.clone(), options, tev);
    {
        let shared = Arc::clone(&shared);
        std::thread::spawn(move || worker::run(shared));
    }
    let app = App {
        shared,
        views: Arc::new(Views::new()),
        access: Arc::new(Access {
            any_host: hosts.iter().any(|h| h == "*"),
            hosts,
            addresses,
            interfaces: ip.is_unspecified().then(|| Interfaces::new(all)),
            token: token.clone(),
            cookie: format!("prism-token-{}", addr.port()),
        }),
        connections: Arc::default(),
        clients: Arc::new(AtomicUsize::new(0)),
        explains: Arc::new(Semaphore::new(views::MAX_RENDERS)),
    };
    let connections = Arc::clone(&app.connections);
    let router = Router::new()
        .route("/", get(page))
        .route("/app.js", get(script))
        .route("/app.css", get(style))
        .route("/events", get(events))
        .route("/picture", get(picture))
        .route("/save.png", get(save_png))
        .route("/save.exr", get(save_exr))
        .route("/explain", get(explain))
        .route("/aov.png", get(aov))
        .route("/stats", get(stats))
        .layer(middleware::from_fn_with_state(app.clone(), guard))
        .with_state(app);
    // Control characters in the path must not drive the terminal.
    let scene = Shown(args.scene.display());
    // Not println!: a closed stdout (a script that read the URL and went)
    // must not stop the server.
    let say = |line: String| {
        use std::io::Write;
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{line}").and_then(|()| out.flush());
    };
    match &token {
        None => say(format!("prism: previewing {scene} at http://{addr}/")),
        Some(token) => {
            // Unspecified: reachable on loopback too, printed first.
            let local = if ip.is_unspecified() {
                SocketAddr::new(IpAddr::from([127, 0, 0, 1]), addr.port())
            } else {
                addr
            };
            eprintln!(
                "warning: --bind {}: the preview is reachable from the network, over plain HTTP; \
                 anyone with the URL's token can see the scene's pictures and make it render",
                args.bind
            );
            say(format!(
                "prism: previewing {scene} at http://{local}/?token={token}"
            ));
            // Other machines: by the interfaces' addresses (a laptop on
            // the network seldom resolves this machine's name); by the
            // name only when no address can be reached.
            let port = addr.port();
            if ip.is_unspecified() {
                for a in &reachable {
                    let a = SocketAddr::new(*a, port);
                    say(format!(
                        "prism: from other machines: http://{a}/?token={token}"
                    ));
                }
                if let Some(name) = name.filter(|_| reachable.is_empty()) {
                    say(format!(
                        "prism: from other machines: http://{}:{port}/?token={token}",
                        escape_controls(&name)
                    ));
                }
            }
        }
    }
    conn::serve(listener, router, connections).await;
    ExitCode::SUCCESS
}

fn refuse(status: StatusCode, message: impl Into<String>) -> Response {
    let mut r = (status, message.into()).into_response();
    r.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    r
}

/// The host part of a Host header, lower case, without the port or the
/// brackets of an IPv6 address.
fn host_name(host: &str) -> String {
    let host = host.trim().to_ascii_lowercase();
    if let Some(rest) = host.strip_prefix('[') {
        return rest.split(']').next().unwrap_or_default().to_string();
    }
    match host.rsplit_once(':') {
        Some((name, port)) if port.chars().all(|c| c.is_ascii_digit()) => name.to_string(),
        _ => host,
    }
}

/// Equal in time independent of where they differ.
fn same_secret(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0, |d, (x, y)| d | (x ^ y)) == 0
}

fn query_token(request: &Request) -> Option<String> {
    request.uri().query()?.split('&').find_map(|pair| {
        let value = pair.strip_prefix("token=")?;
        urlencoding::decode(value).ok().map(|v| v.into_owned())
    })
}

fn cookie_token(headers: &HeaderMap, name: &str) -> Option<String> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(';'))
        .find_map(|c| {
            c.trim()
                .strip_prefix(name)?
                .strip_prefix('=')
                .map(str::to_string)
        })
}

fn header_token(headers: &HeaderMap) -> Option<String> {
    let value = headers.get(header::AUTHORIZATION)?.to_str().ok()?;
    let (scheme, token) = value.split_once(' ')?;
    matches!(scheme.to_ascii_lowercase().as_str(), "token" | "bearer")
        .then(|| token.trim().to_string())
}

/// Every request passes here: one Host header, one of ours (DNS
/// rebinding); nothing a page of another site asked for; and in network
/// mode the token.
async fn guard(State(app): State<App>, request: Request, next: Next) -> Response {
    let headers = request.headers();
    let mut all = headers.get_all(header::HOST).iter();
    let (Some(host), None) = (all.next(), all.next()) else {
        return refuse(StatusCode::BAD_REQUEST, "one Host header is needed\n");
    };
    let Ok(host) = host.to_str() else {
        return refuse(StatusCode::BAD_REQUEST, "the Host header is not text\n");
    };
    if request
        .uri()
        .authority()
        .is_some_and(|a| !a.as_str().eq_ignore_ascii_case(host))
    {
        return refuse(
            StatusCode::BAD_REQUEST,
            "the URL and the Host header differ\n",
        );
    }
    let name = host_name(host);
    // The address the request came in on, as an IP literal, is ours
    // whichever interface it is: a rebinding attack needs a name.
    // So is an address of this machine's interfaces when bound to all of
    // them (a client that typed the machine's address, port forwarding),
    // and the bound address.
    let local = request.extensions().get::<LocalAddr>().map(|l| l.0.ip());
    let literal = name.parse::<IpAddr>().ok().map(|i| i.to_canonical());
    let ours = app.access.any_host
        || app.access.hosts.contains(&name)
        || literal.is_some_and(|i| {
            Some(i) == local.map(|l| l.to_canonical())
                || app.access.addresses.contains(&i)
                || app
                    .access
                    .interfaces
                    .as_ref()
                    .is_some_and(|f| f.contains(i))
        });
    if !ours {
        return refuse(
            StatusCode::MISDIRECTED_REQUEST,
            format!("this preview does not answer to {name}; see --allow-host\n"),
        );
    }
    // Cross-site: a page elsewhere may link to the preview (a top-level
    // navigation to the page itself) but not frame it or make it work
    // (debug views, pictures).
    let navigation = request.method() == Method::GET
        && request.uri().path() == "/"
        && headers
            .get("sec-fetch-mode")
            .is_none_or(|m| m.as_bytes() == b"navigate")
        && headers
            .get("sec-fetch-dest")
            .is_none_or(|d| d.as_bytes() == b"document");
    let site = headers.get("sec-fetch-site").map(HeaderValue::as_bytes);
    let cross_site = site.is_some_and(|s| s != b"same-origin" && s != b"none");
    let foreign_origin = headers
        .get(header::ORIGIN)
        .is_some_and(|o| o.to_str().ok() != Some(format!("http://{host}").as_str()));
    if (cross_site || foreign_origin) && !navigation {
        return refuse(
            StatusCode::FORBIDDEN,
            "cross-site requests are refused: open the preview's own page\n",
        );
    }
    let Some(token) = &app.access.token else {
        return next.run(request).await;
    };
    let from_query = query_token(&request).is_some_and(|t| same_secret(&t, token));
    let from_cookie =
        cookie_token(headers, &app.access.cookie).is_some_and(|t| same_secret(&t, token));
    let from_header = header_token(headers).is_some_and(|t| same_secret(&t, token));
    if !(from_query || from_cookie || from_header) {
        if navigation {
            let mut r = typed("text/html; charset=utf-8", TOKEN_PAGE);
            *r.status_mut() = StatusCode::FORBIDDEN;
            return r;
        }
        return refuse(
            StatusCode::FORBIDDEN,
            "this preview needs its token: open the URL prism serve printed\n",
        );
    }
    let mut response = next.run(request).await;
    if from_query && !from_cookie {
        // Kept for the page's own requests (SameSite: not sent by others).
        let cookie = format!(
            "{}={token}; Path=/; HttpOnly; SameSite=Strict",
            app.access.cookie
        );
        if let Ok(v) = HeaderValue::from_str(&cookie) {
            response.headers_mut().append(header::SET_COOKIE, v);
        }
    }
    response
}

/// Asks for the token when the page is opened without it.
const TOKEN_PAGE: &str = "<!doctype html><meta charset=utf-8><title>Prism preview: token</title>\
<p>This preview needs the token in the URL that <code>prism serve</code> printed.</p>\
<form method=get action=/><label>Token <input name=token autocomplete=off size=50></label> \
<button>Open</button></form>\n";

fn typed(content_type: &'static str, body: impl IntoResponse) -> Response {
    let mut r = body.into_response();
    r.headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    r.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    r
}

async fn page() -> Response {
    let mut r = typed("text/html; charset=utf-8", include_str!("page/index.html"));
    // Not in another site's frame (clickjacking); the token in the URL is
    // not sent on as a referrer.
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static("frame-ancestors 'none'"),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    r
}

async fn script() -> Response {
    typed(
        "text/javascript; charset=utf-8",
        include_str!("page/app.js"),
    )
}

async fn style() -> Response {
    typed("text/css; charset=utf-8", include_str!("page/app.css"))
}

/// Counts for scripts and tests: connections, pages, on-demand renders.
async fn stats(State(app): State<App>) -> Response {
    let json = serde_json::json!({
        "connections": app.connections.count(),
        "pages": app.clients.load(Ordering::SeqCst),
        "renders": app.views.counts(),
    });
    typed("application/json", json.to_string())
}

/// Server-sent events: the status, then the current picture, then every
/// change as it happens.
async fn events(State(app): State<App>) -> Response {
    if app.clients.fetch_add(1, Ordering::SeqCst) >= MAX_CLIENTS {
        app.clients.fetch_sub(1, Ordering::SeqCst);
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            format!("too many preview pages open ({MAX_CLIENTS} at most): close one\n"),
        )
            .into_response();
    }
    // Under the status lock, which the worker holds while it sends one:
    // every status after this first one comes as an event, once.
    let (receiver, status) = {
        let status = app.shared.status.lock().unwrap_or_else(|p| p.into_inner());
        (app.shared.events.subscribe(), status.clone())
    };
    let first = Event::default()
        .event("status")
        .data(serde_json::to_string(&status).unwrap_or_default());
    let guard = ClientGuard(Arc::clone(&app.clients));
    let updates = stream::unfold((receiver, guard), |(mut receiver, guard)| async move {
        let event = match receiver.recv().await {
            Ok((name, data)) => Event::default().event(name).data(data.as_str()),
            // A page too slow to keep up misses events and reloads the
            // picture.
            Err(RecvError::Lagged(_)) => Event::default().event("lagged").data("{}"),
            Err(RecvError::Closed) => return None,
        };
        Some((Ok::<Event, Infallible>(event), (receiver, guard)))
    });
    let stream = stream::once(async { Ok::<Event, Infallible>(first) }).chain(updates);
    Sse::new(stream)
        .keep_alive(KeepAlive::default())
        .into_response()
}

/// Counts an open event stream until it closes.
struct ClientGuard(Arc<AtomicUsize>);

impl Drop for ClientGuard {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

fn refused(why: Refused) -> Response {
    match why {
        Refused::NoScene => refuse(StatusCode::CONFLICT, "no scene has loaded yet\n"),
        Refused::Busy => {
            let mut r = refuse(StatusCode::SERVICE_UNAVAILABLE, "busy; try again\n");
            r.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
            r
        }
        Refused::Failed(e) if e.contains("not finished") => {
            refuse(StatusCode::CONFLICT, format!("{e}\n"))
        }
        Refused::Failed(e) => refuse(StatusCode::INTERNAL_SERVER_ERROR, format!("{e}\n")),
    }
}

fn numeric(r: &mut Response, name: &'static str, value: impl ToString) {
    if let Ok(v) = HeaderValue::from_str(&value.to_string()) {
        r.headers_mut().insert(name, v);
    }
}

/// The current picture: little-endian f32 RGB, row-major, its size and
/// generation in headers. Copied once per change and shared by every
/// request; sent in pieces, so a client that stops reading is noticed.
async fn picture(State(app): State<App>) -> Response {
    let snapshot = match app.views.picture(&app.shared).await {
        Ok(s) => s,
        Err(why) => return refused(why),
    };
    const PIECE: usize = 1 << 20;
    let bytes = snapshot.bytes.clone();
    let length = bytes.len();
    let pieces = (0..length)
        .step_by(PIECE)
        .map(move |at| Ok::<_, Infallible>(bytes.slice(at..(at + PIECE).min(length))));
    let mut r = typed(
        "application/octet-stream",
        Body::from_stream(stream::iter(pieces)),
    );
    numeric(&mut r, "content-length", length);
    numeric(&mut r, "x-prism-generation", snapshot.generation);
    numeric(&mut r, "x-prism-width", snapshot.width);
    numeric(&mut r, "x-prism-height", snapshot.height);
    numeric(&mut r, "x-prism-final", snapshot.finished);
    r
}

/// The finished picture, written as `prism render` writes it.
async fn save(app: &App, kind: Kind) -> Response {
    let finished = app.shared.picture.lock().is_ok_and(|p| p.film.is_some());
    if !finished {
        return refuse(StatusCode::CONFLICT, "the render is not finished yet\n");
    }
    let (ext, content_type) = match kind {
        Kind::Exr => ("exr", "image/x-exr"),
        _ => ("png", "image/png"),
    };
    match app.views.get(&app.shared, kind).await {
        Ok(made) => {
            let mut r = typed(content_type, made.bytes.clone());
            let disposition = format!("attachment; filename=\"render.{ext}\"");
            if let Ok(v) = HeaderValue::from_str(&disposition) {
                r.headers_mut().insert(header::CONTENT_DISPOSITION, v);
            }
            r
        }
        Err(why) => refused(why),
    }
}

#[derive(Deserialize)]
struct SaveQuery {
    /// Exposure in stops (the page's slider); absent: the scene's.
    ev: Option<String>,
}

/// The PNG at the exposure asked for, as `prism render --exposure EV`
/// writes it; the scene's exposure when none is given.
async fn save_png(State(app): State<App>, Query(q): Query<SaveQuery>) -> Response {
    let ev = match q.ev.as_deref().map(str::trim) {
        None | Some("") => None,
        Some(text) => match text.parse::<f64>() {
            Ok(ev) if (-MAX_EV..=MAX_EV).contains(&ev) => Some(ev),
            _ => {
                return refuse(
                    StatusCode::BAD_REQUEST,
                    format!("ev: expected a number of stops between -{MAX_EV} and {MAX_EV}\n"),
                );
            }
        },
    };
    let mut r = save(&app, Kind::png(ev)).await;
    if r.status().is_success() {
        let shown = ev.or_else(|| app.shared.last_scene().map(|(_, s, _)| s.exposure));
        if let Some(ev) = shown {
            numeric(&mut r, "x-prism-exposure", ev);
        }
    }
    r
}

/// The exposure range `prism render --exposure` takes.
const MAX_EV: f64 = 64.0;

async fn save_exr(State(app): State<App>) -> Response {
    save(&app, Kind::Exr).await
}

#[derive(Deserialize)]
struct PixelQuery {
    x: u32,
    y: u32,
    #[serde(default)]
    sample: usize,
}

/// `prism explain --json` for a pixel of the last good scene, with each
/// ray's segment projected onto the picture (`screen`: x0, y0, x1, y1),
/// its shadow feelers' too (`kind` "feeler", `blocked`: ending at the
/// blocker), and the scene in outline for the 3D view (`space`).
async fn explain(State(app): State<App>, Query(q): Query<PixelQuery>) -> Response {
    let Some((scene, settings, _)) = app.shared.last_scene() else {
        return refuse(StatusCode::CONFLICT, "no scene has loaded yet\n");
    };
    // A few at once; some more wait (and go if their client goes).
    let Some(_slot) = app.views.wait_slot() else {
        return refused(Refused::Busy);
    };
    let Ok(_permit) = app.explains.acquire().await else {
        return refused(Refused::Busy);
    };
    let result = tokio::task::spawn_blocking(move || {
        let e = prism::render::explain::explain(&scene, &settings, q.x, q.y, q.sample)?;
        let mut json = serde_json::to_value(&e).map_err(|e| e.to_string())?;
        let mut segments = Vec::new();
        let (w, h) = (settings.width, settings.height);
        let project = |p| scene.camera.project(p, w, h);
        for node in e.tree.nodes() {
            let origin = glam::DVec3::from_array(node.origin);
            let direction = glam::DVec3::from_array(node.direction);
            // A camera ray is seen end-on: it starts at its pixel.
            let start = if node.depth == 1 {
                Some((f64::from(q.x) + 0.5, f64::from(q.y) + 0.5))
            } else {
                project(origin)
            };
            let end = match &node.hit {
                Some(hit) => project(glam::DVec3::from_array(hit.point)),
                // A miss: as much of the ray as lies in front of the camera.
                None => [1e3, 1e2, 10.0, 1.0]
                    .into_iter()
                    .find_map(|t| project(origin + direction * t)),
            };
            if let (Some(a), Some(b)) = (start, end) {
                segments.push(serde_json::json!({
                    "kind": node.kind, "depth": node.depth, "screen": [a.0, a.1, b.0, b.1]
                }));
            }
            // Its shadow feelers: to the light, or to what blocked them.
            for (light, l) in node.lights.iter().enumerate() {
                for (index, f) in l.feeler_points.iter().enumerate() {
                    let from = glam::DVec3::from_array(f.origin);
                    let towards = glam::DVec3::from_array(f.direction);
                    let to = match (f.blocker_distance, f.on_light) {
                        (Some(t), _) => from + towards * t,
                        (None, Some(p)) => glam::DVec3::from_array(p),
                        // A directional light: a stretch towards it.
                        (None, None) => from + towards * 1e2,
                    };
                    if let (Some(a), Some(b)) = (project(from), project(to)) {
                        segments.push(serde_json::json!({
                            "kind": "feeler", "depth": node.depth, "light": light,
                            "feeler": index, "blocked": f.blocked_by.is_some(),
                            "screen": [a.0, a.1, b.0, b.1]
                        }));
                    }
                }
            }
        }
        json["segments"] = serde_json::Value::Array(segments);
        json["space"] = space::outline(&scene);
        Ok::<_, String>(json.to_string())
    })
    .await;
    match result {
        Ok(Ok(json)) => typed("application/json", json),
        Ok(Err(message)) => (StatusCode::BAD_REQUEST, message).into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

#[derive(Deserialize)]
struct AovQuery {
    name: String,
}

/// A debug view of the last good scene, in false colour; for the heat
/// ramps, the value shown white in `x-prism-ramp-top`.
async fn aov(State(app): State<App>, Query(q): Query<AovQuery>) -> Response {
    let aov: prism::render::aov::Aov = match q.name.parse() {
        Ok(a) => a,
        Err(e) => return refuse(StatusCode::BAD_REQUEST, e),
    };
    let generation = app.shared.scene_generation.load(Ordering::SeqCst);
    match app.views.get(&app.shared, Kind::View(aov.name())).await {
        Ok(made) => {
            let mut r = typed("image/png", made.bytes.clone());
            numeric(&mut r, "x-prism-generation", generation);
            if let Some(top) = made.top {
                numeric(&mut r, "x-prism-ramp-top", top);
            }
            r
        }
        Err(why) => refused(why),
    }
}
