"""The small HTTP server the browser tests load Foxglove Studio from: the host page, React 17's
UMD builds, studio-base's prebuilt assets, the layout and the recording — with byte ranges,
which Foxglove's remote-file source reads an MCAP file by. Loopback only, in a thread."""

from __future__ import annotations

import http.server
import mimetypes
import re
import threading
from pathlib import Path

HOST = Path(__file__).resolve().parent / "host"
MODULES = HOST / "node_modules"


def routes(layout: Path, recording: Path) -> dict[str, Path]:
    return {"/": HOST / "index.html", "/host.js": HOST / "host.js",
            "/vendor/react.js": MODULES / "react/umd/react.production.min.js",
            "/vendor/react-dom.js": MODULES / "react-dom/umd/react-dom.production.min.js",
            "/layout.json": layout, "/run.mcap": recording}


class HostServer:
    """`with HostServer(layout, recording) as url:` serves until the block ends."""

    def __init__(self, layout: Path, recording: Path):
        table = routes(layout, recording)
        assets = MODULES / "@foxglove/studio-base/assets"

        class Handler(http.server.BaseHTTPRequestHandler):
            def log_message(self, *args) -> None:  # quiet: pytest shows failures
                pass

            def do_GET(self) -> None:  # noqa: N802 - the stdlib's name
                path = self.path.split("?", 1)[0]
                file = table.get(path)
                if file is None and path.startswith("/assets/"):
                    candidate = (assets / path[len("/assets/"):]).resolve()
                    file = candidate if candidate.parent == assets.resolve() else None
                if file is None or not file.is_file():
                    self.send_error(404)
                    return
                data = file.read_bytes()
                kind = mimetypes.guess_type(file.name)[0] or "application/octet-stream"
                if file.suffix == ".wasm":
                    kind = "application/wasm"
                m = re.fullmatch(r"bytes=(\d+)-(\d*)", self.headers.get("Range", ""))
                if m:
                    start = int(m.group(1))
                    end = min(int(m.group(2)) if m.group(2) else len(data) - 1, len(data) - 1)
                    self.send_response(206)
                    self.send_header("Content-Range", f"bytes {start}-{end}/{len(data)}")
                    data = data[start:end + 1]
                else:
                    self.send_response(200)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(data)))
                self.send_header("Accept-Ranges", "bytes")
                self.send_header("Access-Control-Allow-Origin", "*")
                self.end_headers()
                self.wfile.write(data)

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        self._thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    def __enter__(self) -> str:
        self._thread.start()
        return self.url

    def __exit__(self, *exc: object) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
