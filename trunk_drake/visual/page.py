"""Standalone HTML of a Meshcat scene: Drake's `StaticHtml()`, made fully offline, plus our player.

`StaticHtml()` inlines meshcat.js (three.js included) and every scene command as base64 data
URLs. Its JavaScript still names a few web addresses: documentation links, and the WebXR
controller models it would fetch from a CDN in VR mode (unreachable in a static page). They are
blanked, so the page names no external address at all (XML namespace identifiers aside, which
are never fetched) and `external_urls` checks it.
"""

from __future__ import annotations

import base64
import json
import re
from importlib.resources import files
from pathlib import Path

import numpy as np

URL = re.compile(r"""(?:https?|wss?|ftp)://[^\s"'`()<>\\]+""")
NAMESPACES = ("http://www.w3.org/",)  # identifiers of XML namespaces (createElementNS), never fetched
ACTIVATION_RGB = ((0.23, 0.30, 0.75), (0.98, 0.80, 0.20), (0.85, 0.08, 0.08))  # 0, scale / 2, scale
LEGEND_STYLE = ("position:fixed;left:12px;bottom:12px;padding:8px 10px;background:rgba(255,255,255,0.85);"
                "font:13px sans-serif;color:#222;border-radius:4px;max-width:40vw")


def external_urls(html: str) -> list[str]:
    """Web addresses named anywhere in the page (XML namespace identifiers excepted)."""
    return [u for u in URL.findall(html) if not u.startswith(NAMESPACES)]


def standalone_html(meshcat, title: str, legend: str, player: dict | None = None) -> str:
    """The scene of `meshcat` as one HTML file that needs no network, with a title and a legend
    (HTML, see `activation_legend`, `group_legend`); with `player` data (see `player_data`)
    the muscle lines follow the recording and show activation."""
    html = URL.sub(lambda m: m.group(0) if m.group(0).startswith(NAMESPACES) else "", meshcat.StaticHtml())
    html = html.replace("<title>Drake MeshCat</title>", f"<title>{_escape(title)}</title>", 1)
    extra = (f'<div id="trunk-drake-legend" style="{LEGEND_STYLE}"><div style="font-weight:bold;margin-bottom:4px">'
             f"{_escape(title)}</div>{legend}</div>\n")
    if player is not None:
        script = files("trunk_drake.visual").joinpath("player.js").read_text()
        payload = json.dumps(player, separators=(",", ":")).replace("</", "<\\/")
        extra += (f'<script type="application/json" id="trunk-drake-player">{payload}</script>\n'
                  f"<script>\n{script}</script>\n")
    html = html.replace("</body>", extra + "</body>", 1)
    left = external_urls(html)
    if left:
        raise RuntimeError(f"the exported page still names web addresses {left[:3]}; it would not work offline")
    return html


def activation_legend(scale: float) -> str:
    stops = ",".join(_css(rgb) for rgb in ACTIVATION_RGB)
    return (f'<div>muscle activation</div><div style="height:10px;width:200px;background:linear-gradient(to right,{stops})">'
            f'</div><div style="display:flex;justify-content:space-between;width:200px"><span>0</span><span>{scale:g}</span></div>')


def ghost_legend(label: str, note: str, model_rgb, data_rgb) -> str:
    return (f"<div>{_swatch(model_rgb)} model (with its muscles)</div>"
            f"<div>{_swatch(data_rgb)} data: {_escape(label)} ({_escape(note)})</div>")


def group_legend(colours: dict[str, tuple]) -> str:
    return "".join(f"<div>{_swatch(rgb)} {_escape(name.replace('_', ' '))}</div>" for name, rgb in colours.items())


def activation_scale(activation: np.ndarray) -> float:
    """The activation shown in full colour: the run's largest, rounded up to 0.01 (at most 1)."""
    return float(min(np.ceil(max(float(np.max(activation)), 0.01) * 100) / 100, 1.0))


def player_data(fps: float, segment_paths, muscle_paths, vertices, wrap_points: np.ndarray, activation: np.ndarray) -> dict:
    """What player.js needs: scene paths, polyline vertices, wrap points per frame (int16, ~15 um)
    and activations per frame (uint8 of activation / scale; scale = the largest activation)."""
    frames = len(activation)
    flat = wrap_points.reshape(frames, -1, 3)
    low, high = flat.min(axis=(0, 1)), flat.max(axis=(0, 1))
    offset = (low + high) / 2
    scale = max(float((high - low).max()) / 2 / 32000, 1e-9)
    scaled = activation_scale(activation)
    return {
        "fps": fps, "frames": frames,
        "segments": [_node(p) for p in segment_paths], "muscles": [_node(p) for p in muscle_paths],
        "vertices": [[[v[0], *[round(float(x), 7) for x in v[1:]]] if v[0] >= 0 else v for v in verts] for verts in vertices],
        "wrap": {"points": flat.shape[1], "offset": offset.tolist(), "scale": scale,
                 "data": _b64(np.round((flat - offset) / scale).astype("<i2"))},
        "activation": {"scale": scaled, "data": _b64(np.round(np.clip(activation / scaled, 0, 1) * 255).astype(np.uint8))},
        "colours": ACTIVATION_RGB,
    }


def scene_commands(html: str) -> list[dict]:
    """The Meshcat commands embedded in a page (msgpack in base64 data URLs), decoded."""
    import msgpack

    return [msgpack.unpackb(base64.b64decode(d), raw=False, strict_map_key=False)
            for d in re.findall(r'fetch\("data:application/octet-binary;base64,([^"]+)"\)', html)]


def recorded_positions(html: str) -> dict[str, np.ndarray]:
    """Per animated scene path, its recorded position at every frame (n_frames, 3)."""
    (animation,) = [c for c in scene_commands(html) if c["type"] == "set_animation"]
    return {a["path"]: np.array([k["value"] for k in next(t for t in a["clip"]["tracks"] if t["name"] == ".position")["keys"]])
            for a in animation["animations"]}


def embedded_player(html: str) -> dict:
    """The player data of an animation page (see `player_data`)."""
    return json.loads(re.search(r'<script type="application/json" id="trunk-drake-player">(.*?)</script>', html, re.S).group(1))


def write_page(html: str, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html, encoding="utf-8")
    return path


def _node(path: str) -> list[str]:
    return [p for p in path.split("/") if p]


def _b64(array: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(array).tobytes()).decode("ascii")


def _css(rgb) -> str:
    return f"rgb({','.join(str(round(255 * c)) for c in rgb[:3])})"


def _swatch(rgb) -> str:
    return f'<span style="display:inline-block;width:10px;height:10px;background:{_css(rgb)};border:1px solid #555"></span>'


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
