"""The local web server of the live page: Starlette (ASGI) + uvicorn, one WebSocket.

Routes: ``/`` the page, ``/static/<file>`` its script and style (served only from this
package's ``static`` folder; anything that resolves outside it is a 404), ``/ws`` the
WebSocket. Every client message is a JSON object of at most :data:`MAX_MESSAGE`
bytes, validated by :func:`~expertise_irl.live.session.validate_message`; a bad one
gets ``{"type": "error", "message": ...}`` and the connection stays open. A page from
another origin cannot open the socket, and with a loopback bind only loopback host
names are answered (no DNS rebinding).
"""

from __future__ import annotations

import asyncio
import ipaddress
import json
import socket
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .session import LiveSession

if TYPE_CHECKING:
    from starlette.websockets import WebSocket

MAX_MESSAGE = 1024  # bytes; the largest real message is about 40
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "::1", "[::1]")


def static_dir() -> Path:
    """The package's own folder of page files."""
    return Path(str(resources.files("expertise_irl") / "live" / "static"))


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def create_app(session: LiveSession, *, allowed_hosts: list[str] | None = None):
    """The ASGI application serving ``session``. ``allowed_hosts`` (None: any) limits the Host
    header answered."""
    from starlette.applications import Starlette
    from starlette.middleware import Middleware
    from starlette.middleware.trustedhost import TrustedHostMiddleware
    from starlette.responses import FileResponse, PlainTextResponse
    from starlette.routing import Mount, Route, WebSocketRoute
    from starlette.staticfiles import StaticFiles
    from starlette.websockets import WebSocketDisconnect

    folder = static_dir()
    lock = asyncio.Lock()
    clients: set[WebSocket] = set()

    async def index(request):
        return FileResponse(folder / "index.html", headers=_headers(request.headers.get("host", "")))

    async def not_found(request):
        return PlainTextResponse("not found", status_code=404)

    async def ws_endpoint(ws: WebSocket) -> None:
        origin = ws.headers.get("origin")
        host = ws.headers.get("host", "")
        if origin is not None and origin not in (f"http://{host}", f"https://{host}"):
            await ws.close(code=1008)  # a page of another site may not drive the robot
            return
        await ws.accept()
        clients.add(ws)
        try:
            async with lock:
                await _send(ws, session.static_message())
            while True:
                event = await ws.receive()
                if event["type"] == "websocket.disconnect":
                    break
                msg, problem = _decode(event.get("text"))
                if problem is not None:
                    await _send(ws, {"type": "error", "message": problem})
                    continue
                await _deliver(ws, await _run(lock, session.handle, msg, defer=True), clients)
                if session.refine_pending:  # an episode ended: the page shows it, then the set is refined
                    await _deliver(ws, await _run(lock, _finish, session), clients)
        except WebSocketDisconnect:
            pass
        finally:
            clients.discard(ws)

    middleware = []
    if allowed_hosts is not None:
        middleware.append(Middleware(TrustedHostMiddleware, allowed_hosts=allowed_hosts))
    routes = [
        Route("/", index),
        WebSocketRoute("/ws", ws_endpoint),
        Mount("/static", app=StaticFiles(directory=folder, follow_symlink=False), name="static"),
        Route("/{rest:path}", not_found),
    ]
    return Starlette(routes=routes, middleware=middleware)


async def _run(lock: asyncio.Lock, fn: Callable[..., list[dict[str, Any]]], *args,
               **kwargs) -> list[dict[str, Any]]:
    """``fn``'s replies, run in a worker thread (a solve or a refinement does not stop the server)
    while holding ``lock`` (one message at a time); an exception becomes an error reply."""
    async with lock:
        try:
            return await asyncio.to_thread(fn, *args, **kwargs)
        except Exception as exc:  # never let one message take the server down
            return [{"type": "error", "message": f"could not handle the message: {exc}"}]


def _finish(session: LiveSession) -> list[dict[str, Any]]:
    """The episode's refinement, unless another page's message ran it meanwhile."""
    return session.finish_episode() if session.refine_pending else []


def _headers(host: str) -> dict[str, str]:
    return {
        "Content-Security-Policy": (f"default-src 'self'; connect-src 'self' ws://{host}; "
                                    "img-src 'self' data:; frame-ancestors 'none'"),
        "X-Content-Type-Options": "nosniff",
        "Referrer-Policy": "no-referrer",
        "Cache-Control": "no-store",
    }


def _decode(text: str | None) -> tuple[Any, str | None]:
    """The JSON of a client's frame, or None and why it is refused."""
    if text is None:
        return None, "messages must be JSON text, not binary"
    if len(text.encode("utf-8", "replace")) > MAX_MESSAGE:
        return None, f"message too large (limit {MAX_MESSAGE} bytes)"
    try:
        return json.loads(text), None
    except ValueError:
        return None, "malformed message: not valid JSON"


async def _send(ws: WebSocket, doc: dict[str, Any]) -> None:
    await ws.send_text(json.dumps(doc, allow_nan=False))


async def _deliver(ws: WebSocket, replies: list[dict[str, Any]], clients: set[WebSocket]) -> None:
    """A state reply to every open page (one that cannot be reached is dropped), the rest to ``ws``."""
    for r in replies:
        if r["type"] == "state":  # every open page follows the same session
            for c in list(clients):
                try:
                    await _send(c, r)
                except Exception:
                    clients.discard(c)
        else:
            await _send(ws, r)


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: any free port)."""
    family = socket.AF_INET6 if ":" in host.strip("[]") else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind((host.strip("[]"), port))
    sock.listen(128)
    sock.set_inheritable(True)
    return sock


def url_of(sock: socket.socket) -> str:
    host, port = sock.getsockname()[:2]
    shown = f"[{host}]" if ":" in host else host
    return f"http://{shown}:{port}/"


def serve(session: LiveSession, sock: socket.socket, *,
          on_ready: Callable[[str], None] | None = None) -> None:
    """Serve ``session`` on the bound ``sock`` until interrupted (Ctrl-C)."""
    import uvicorn

    host = sock.getsockname()[0]
    allowed = [*LOOPBACK_NAMES] if is_loopback(host) else None
    app = create_app(session, allowed_hosts=allowed)
    # Frames up to 1 MiB reach the handler (and get an error reply if over MAX_MESSAGE); a larger
    # one is refused by the WebSocket layer, which closes the connection (code 1009).
    config = uvicorn.Config(app, log_level="warning", lifespan="off", ws_max_size=2**20,
                            access_log=False)
    server = uvicorn.Server(config)
    if on_ready is not None:
        on_ready(url_of(sock))
    server.run(sockets=[sock])
