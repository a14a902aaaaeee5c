//! `prism serve`: a live preview in the browser. The page shows the render
//! as it happens (a coarse pass, then tiles at full resolution, then the
//! full sample count), follows every save of the scene file and the files
//! it reads, shows a broken scene's errors with their lines, and explains
//! any pixel (`prism explain` in the page). A front end beside the CLI:
//! the library knows nothing of HTTP.
//!
//! Safe by default: it binds 127.0.0.1; a request whose Host header is not
//! the address it serves is refused (421), against DNS rebinding; it serves
//! its embedded page and the images it rendered, no file from disk; pages
//! are limited to `MAX_CLIENTS` event streams.

mod worker;

use std::convert::Infallible;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use axum::Router;
use axum::extract::{Query, Request, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use clap::Args;
use futures_util::stream::{self, StreamExt};
use serde::Deserialize;
use tokio::sync::broadcast::error::RecvError;

use crate::commands::{BAD_INPUT, LoadArgs};
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
    /// Address to listen on; anything but 127.0.0.1 or ::1 exposes the
    /// preview (and the scene's pictures) to the network.
    #[arg(long, default_value = "127.0.0.1")]
    bind: std::net::IpAddr,
    /// Also stream the tiles to the tev image viewer at HOST:PORT.
    #[arg(long, value_name = "HOST:PORT")]
    display_server: Option<String>,
    #[command(flatten)]
    load: LoadArgs,
}

#[derive(Clone)]
struct App {
    shared: Arc<Shared>,
    /// Host header values this server answers to.
    hosts: Arc<Vec<String>>,
    clients: Arc<AtomicUsize>,
}

pub fn run(args: &ServeArgs) -> ExitCode {
    let options = match args.load.options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    if !args.scene.is_file() {
        eprintln!("error: {}: no such scene file", args.scene.display());
        return ExitCode::from(BAD_INPUT);
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
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
    let mut hosts = vec![addr.to_string()];
    if addr.ip().is_loopback() {
        hosts.push(format!("localhost:{}", addr.port()));
    }
    let tev = match &args.display_server {
        None => None,
        Some(address) => match crate::tev::Tev::connect(address, &args.scene.display().to_string())
        {
            Ok(t) => Some(t),
            Err(e) => {
                eprintln!("error: {e}");
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
        hosts: Arc::new(hosts),
        clients: Arc::new(AtomicUsize::new(0)),
    };
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
        .layer(middleware::from_fn_with_state(app.clone(), check_host))
        .with_state(app);
    println!(
        "prism: previewing {} at http://{addr}/",
        args.scene.display()
    );
    if let Err(e) = axum::serve(listener, router).await {
        eprintln!("error: the server stopped: {e}");
        return ExitCode::FAILURE;
    }
    ExitCode::SUCCESS
}

/// DNS rebinding: a page from another origin that resolves its own name
/// to 127.0.0.1 sends its own Host header; only ours is served.
async fn check_host(State(app): State<App>, request: Request, next: Next) -> Response {
    let host = request
        .headers()
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or_default();
    if !app.hosts.iter().any(|h| h == host) {
        return (
            StatusCode::MISDIRECTED_REQUEST,
            format!("this preview answers to {} only\n", app.hosts.join(" or ")),
        )
            .into_response();
    }
    next.run(request).await
}

fn typed(content_type: &'static str, body: impl IntoResponse) -> Response {
    let mut r = body.into_response();
    r.headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    r.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    r
}

async fn page() -> Response {
    typed("text/html; charset=utf-8", include_str!("page/index.html"))
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

/// Server-sent events: the status, then the current picture, then every
/// change as it happens.
async fn events(State(app): State<App>) -> Response {
    if app.clients.fetch_add(1, Ordering::SeqCst) >= MAX_CLIENTS {
        app.clients.fetch_sub(1, Ordering::SeqCst);
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            "too many preview pages open\n",
        )
            .into_response();
    }
    let receiver = app.shared.events.subscribe();
    let status = app
        .shared
        .status
        .lock()
        .map(|s| s.clone())
        .unwrap_or_default();
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

/// The current picture, as the events carry it (JSON, f32 RGB base64).
async fn picture(State(app): State<App>) -> Response {
    let p = app
        .shared
        .picture
        .lock()
        .map(|p| p.clone())
        .unwrap_or_default();
    let generation = app.shared.status.lock().map(|s| s.generation).unwrap_or(0);
    typed(
        "application/json",
        format!(
            r#"{{"generation":{generation},"width":{},"height":{},"final":{},"data":"{}"}}"#,
            p.width,
            p.height,
            p.film.is_some(),
            worker::encode_pixels(p.pixels.iter().copied())
        ),
    )
}

/// The finished picture, written as `prism render` writes it.
fn save(app: &App, ext: &str, content_type: &'static str) -> Response {
    let film = app.shared.picture.lock().ok().and_then(|p| p.film.clone());
    let Some(film) = film else {
        return (StatusCode::CONFLICT, "the render is not finished yet\n").into_response();
    };
    let scene = app.shared.scene.lock().ok().and_then(|s| s.clone());
    let provenance =
        scene.map(|(scene, settings)| prism::image_io::Provenance::of(&scene, &settings));
    let written = tempfile::tempdir().and_then(|dir| {
        let path = dir.path().join(format!("render.{ext}"));
        prism::image_io::write_film_unless(
            &film,
            &path,
            provenance.as_ref(),
            &std::sync::atomic::AtomicBool::new(false),
        )
        .map_err(std::io::Error::other)?;
        std::fs::read(path)
    });
    match written {
        Ok(bytes) => {
            let mut r = typed(content_type, bytes);
            let disposition = format!("attachment; filename=\"render.{ext}\"");
            if let Ok(v) = HeaderValue::from_str(&disposition) {
                r.headers_mut().insert(header::CONTENT_DISPOSITION, v);
            }
            r
        }
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

async fn save_png(State(app): State<App>) -> Response {
    save(&app, "png", "image/png")
}

async fn save_exr(State(app): State<App>) -> Response {
    save(&app, "exr", "image/x-exr")
}

#[derive(Deserialize)]
struct PixelQuery {
    x: u32,
    y: u32,
    #[serde(default)]
    sample: usize,
}

/// `prism explain --json` for a pixel of the last good scene, with each
/// ray's segment projected onto the picture (`screen`: x0, y0, x1, y1).
async fn explain(State(app): State<App>, Query(q): Query<PixelQuery>) -> Response {
    let Some((scene, settings)) = app.shared.scene.lock().ok().and_then(|s| s.clone()) else {
        return (StatusCode::CONFLICT, "no scene has loaded yet\n").into_response();
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
        }
        json["segments"] = serde_json::Value::Array(segments);
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

/// A debug view of the last good scene, in false colour.
async fn aov(State(app): State<App>, Query(q): Query<AovQuery>) -> Response {
    let aov: prism::render::aov::Aov = match q.name.parse() {
        Ok(a) => a,
        Err(e) => return (StatusCode::BAD_REQUEST, e).into_response(),
    };
    let Some((scene, settings)) = app.shared.scene.lock().ok().and_then(|s| s.clone()) else {
        return (StatusCode::CONFLICT, "no scene has loaded yet\n").into_response();
    };
    let result = tokio::task::spawn_blocking(move || {
        let region = prism::render::Region::full(settings.width, settings.height);
        let out = prism::render::aov::render_aov(&scene, &settings, region, aov, &())
            .map_err(|e| e.to_string())?;
        let film = prism::render::aov::false_colour(&out.film, aov);
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let path = dir.path().join("aov.png");
        prism::image_io::write_film(&film, &path).map_err(|e| e.to_string())?;
        std::fs::read(path).map_err(|e| e.to_string())
    })
    .await;
    match result {
        Ok(Ok(bytes)) => typed("image/png", bytes),
        Ok(Err(message)) => (StatusCode::BAD_REQUEST, message).into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}
