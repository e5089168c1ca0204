"""See the passenger move: Meshcat scenes of the trunk model, recordings and standalone HTML pages."""

from trunk_drake.visual.animation import LiveView, animate, animate_trial, serve, view_html
from trunk_drake.visual.measured import MeasuredMotion, measured_motion

__all__ = ["animate", "view_html", "serve", "LiveView", "MeasuredMotion", "measured_motion", "animate_trial"]
