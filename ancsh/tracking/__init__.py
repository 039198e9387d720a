"""Tracking articulated objects over depth sequences.

- :mod:`.tracker`: :class:`CategoryTracker` (category level: a correspondence provider such as the
  network, warm-started fits with a temporal prior, correspondences carried between network
  frames, re-initialisation), the per-frame record :class:`TrackedFrame` and its :class:`TrackStatus`;
- :mod:`.carried`: the point template that carries correspondences between network frames;
- :mod:`.instance`: :class:`InstanceTracker` (a known URDF model: warm-started articulated ICP);
- :mod:`.stream`: depth-folder sequences in, per-frame JSON lines out (``ancsh track``);
- :mod:`.bench`: ``ancsh bench tracking`` (tracking vs independent per-frame fits).
"""

from .instance import InstanceTracker, InstanceTrackerConfig
from .tracker import CategoryTracker, TrackedFrame, TrackerConfig, TrackStatus

__all__ = ["CategoryTracker", "InstanceTracker", "InstanceTrackerConfig", "TrackStatus", "TrackedFrame", "TrackerConfig"]
