"""The errors PIMM raises on purpose: one base, :class:`PimmError`, and one class per layer.

Catch ``PimmError`` to tell a user's mistake (a bad file, setting or observation) from a bug: the command line
prints a ``PimmError`` as one line and lets anything else show its traceback. Every message names what is
wrong: the file, the field or observation key, and the value. Each class also derives from the built-in
exception a caller would expect (``ValueError``, or ``FileNotFoundError`` for a missing file), so code written
against those keeps working.

=====================  ==============================================================================
class                  raised for
=====================  ==============================================================================
``MissingFileError``   a file or folder that was named does not exist
``WorldError``         world files, meshes, occupancy and corner maps, scenarios and routes
``EnvError``           the simulator's and env's settings: sensors, faults, movers, reset options, actions
``BagError``           rosbags and their messages
``CloudFileError``     point cloud files: PCD, PLY, LAS/LAZ, ``.npy``, KITTI ``.bin``
``ParamsError``        params files and ``--set`` settings
``LocalizerError``     building a localizer: unknown names, config values, maps it cannot use
``ObservationError``   a localizer's input: missing keys, wrong shapes, non-finite values
``PerceptionError``    the network's weights, fingerprint maps and training datasets
``ResultsError``       trial logs, TUM files, stored trials and results folders
``ExperimentError``    experiment definitions: run records, sweep files, trial specs, backends
=====================  ==============================================================================
"""

from __future__ import annotations

from pathlib import Path


class PimmError(Exception):
    """Base of every error PIMM raises on purpose."""


class MissingFileError(PimmError, FileNotFoundError):
    """A file or folder that was named does not exist; the message names it and how to make it."""


class WorldError(PimmError, ValueError):
    """A world, one of its maps, scenarios or routes is unusable."""


class WorldFileError(WorldError):
    """A world file is malformed; the message names the file, the field and the bad value."""

    def __init__(self, path: Path | str, field_name: str, message: str) -> None:
        super().__init__(f"{path}: {field_name}: {message}")
        self.path = str(path)
        self.field = field_name


class MapFileError(WorldError):
    """A map (or a mesh to import) is unusable; the message names the file, the field and the value."""


class StaleMapsError(WorldError, FileNotFoundError):
    """A world's derived maps are missing or were made from another version of the world."""


class RoutePlanningError(WorldError):
    """The world has no room for a route of the asked length and clearance."""


class NoFreeRegionError(WorldError):
    """No place of the map keeps the asked clearance."""


class EnvError(PimmError, ValueError):
    """The simulator or env was given a setting, option or action it cannot use."""


class BagError(PimmError, ValueError):
    """A bag or one of its messages is unusable; the message names the topic and the message's index."""


class CloudFileError(PimmError, ValueError):
    """A point cloud file is unusable; the message names the file, the field or row, and what to give."""


class ParamsError(PimmError, ValueError):
    """A params file or setting names an unknown key or has a value of the wrong type."""


class LocalizerError(PimmError, ValueError):
    """A localizer cannot be built: unknown name, bad config value, or maps it cannot use."""


class ObservationError(PimmError, ValueError):
    """An observation handed to a localizer lacks a key, has the wrong shape or holds non-finite values."""


class PerceptionError(PimmError, ValueError):
    """The network's weights, a fingerprint map or a training dataset is unusable."""


class ResultsError(PimmError, ValueError):
    """A trial log, trajectory file, stored trial or results folder is unusable."""


class ExperimentError(PimmError, ValueError):
    """An experiment's definition (run record, sweep file, trial specs, backend) is unusable."""


class Ros2Error(PimmError, ValueError):
    """A ROS 2 / DDS problem: a bad domain id, discovery range, topic, message or node parameter."""
