"""Errors meant for the user: the CLI prints them as one line and exits non-zero, without a traceback."""


class PlatesynthError(Exception):
    """Base class of every expected, user-facing error."""


class ImageReadError(PlatesynthError):
    """An image file is missing, unreadable, corrupt or of an unsupported kind."""


class ShapeMismatchError(PlatesynthError):
    """Two images (or an image and its mask) that must have the same shape do not."""


class EmptyDatasetError(PlatesynthError):
    """A directory that should hold images holds none."""


class WeightsNotFoundError(PlatesynthError):
    """Network weights could not be found locally nor downloaded."""


class ParameterError(PlatesynthError):
    """A scene parameter or configuration value is unknown, of the wrong type or out of range."""


class DatasetError(PlatesynthError):
    """A dataset directory is inconsistent (missing masks, another dataset in the way, ...)."""


class MetricUndefinedError(PlatesynthError):
    """A metric has no defined value for this input (e.g. naturalness of a constant image)."""


class RenderError(PlatesynthError):
    """A renderer failed (e.g. an error inside Blender)."""


class ExecutorError(PlatesynthError):
    """Batch work could not run where asked (e.g. a Dask scheduler is unreachable, a worker process died)."""


class OutputError(PlatesynthError):
    """An output may not be written where asked (it would replace an input or another kind of output, another
    process writes there, or the place cannot be written)."""
