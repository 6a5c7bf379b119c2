"""A real HTTP server on 127.0.0.1 serving GRIB bodies, with the failures real servers show."""

from __future__ import annotations

import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer


class GribServer:
    """Serves bodies by path; behaviours per path: 'drop' once, 'truncate' N times, 404 when unknown."""

    def __init__(self) -> None:
        self.bodies: dict[str, bytes] = {}
        self.drop_once: set[str] = set()
        self.truncate_times: dict[str, int] = {}
        self.requests: list[tuple[str, str | None]] = []
        server = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args: object) -> None:
                pass

            def do_GET(self) -> None:  # noqa: N802 - http.server's name
                path = self.path.split("?")[0]
                server.requests.append((path, self.headers.get("Range")))
                body = server.bodies.get(path)
                if body is None:
                    self.send_error(404, "Not Found")
                    return
                if server.truncate_times.get(path, 0) > 0:
                    server.truncate_times[path] -= 1
                    body = body[: len(body) * 2 // 3]  # a complete HTTP reply of a cut GRIB file
                start = 0
                range_header = self.headers.get("Range")
                if range_header and path not in server.truncate_times:
                    start = int(range_header.removeprefix("bytes=").split("-")[0])
                    self.send_response(206)
                    self.send_header("Content-Range", f"bytes {start}-{len(body) - 1}/{len(body)}")
                else:
                    self.send_response(200)
                self.send_header("Content-Length", str(len(body) - start))
                self.end_headers()
                if path in server.drop_once:
                    server.drop_once.discard(path)
                    self.wfile.write(body[start : start + (len(body) - start) // 2])
                    self.wfile.flush()
                    self.close_connection = True
                    return
                self.wfile.write(body[start:])

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    @property
    def template(self) -> str:
        port = self.httpd.server_address[1]
        return (
            f"http://127.0.0.1:{port}/{{date}}/{{hour}}/{{remote_file}}?l={{left}}&r={{right}}&token=SECRET42"
        )

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join()
