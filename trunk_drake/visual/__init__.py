"""See the passenger move: Meshcat scenes of the trunk model, recordings and standalone HTML pages."""

from trunk_drake.visual.animation import LiveView, animate, serve, view_html

__all__ = ["animate", "view_html", "serve", "LiveView"]
