"""Image input and output: linear OpenEXR with AOVs, 8-bit sRGB PNG, written atomically.

An ``.exr`` file holds the linear radiance in channels ``R``, ``G``, ``B`` (float32, or half
on request) followed by the AOV channels named in `AOV_CHANNELS` (always float32), and the
render metadata as header attributes prefixed with ``wrt:``. A ``.png`` file holds the
radiance tone-mapped by `tonemap_srgb` only.

Files are written to a temporary file in the target's folder, read back and compared with the
pixels meant (OpenImageIO's PNG writer does not report a failed write: a full disk left a 0-byte
file), and moved into place with `os.replace` (``wrt.files.atomic_path``), so the target is
always either the previous file or the complete new one. Reading checks the file's kind and
its size in pixels before a pixel is allocated.
"""

import contextlib
import os
import sys
import tempfile
import threading
from dataclasses import dataclass, field

import numpy as np

from .console import held_signals
from .errors import WrtError, foreign
from .files import atomic_path, check_regular_file
from .limits import MAX_IMAGE_SIDE

with held_signals():  # a signal while nanobind sets the module up would abort the process
    import OpenImageIO as oiio

AOV_CHANNELS = {
    "depth": ("Z",),
    "normal": ("N.X", "N.Y", "N.Z"),
    "object_id": ("id",),
    "position": ("P.X", "P.Y", "P.Z"),
    "variance": ("var.R", "var.G", "var.B"),
    "spp": ("spp",),
}
"""EXR channel names of each AOV, in component order; a public contract of the file format.

``depth`` is the ray distance to the first hit (scene units, +inf on a miss); ``normal`` the
unit shading normal and ``position`` the hit point (world space); ``object_id`` (channel ``id``) the shape index in
scene-file order (-1 on a miss), stored as float32. ``variance`` is the per-sample variance of
each pixel's RGB estimate (reference images of the regression harness); ``spp`` the samples each
pixel took (adaptive sampling).
"""

SUPPORTED_EXTENSIONS = (".exr", ".png")
METADATA_PREFIX = "wrt:"
_RGB_CHANNELS = ("R", "G", "B")
_MAX_EXACT_ID = 2**24  # largest magnitude up to which every integer is exact in float32
HALF_MAX = 65504.0
"""Largest finite half float: ``--half`` radiance beyond it is stored as this, never as Inf."""
MAX_CHANNELS = 64
"""Most channels an image read may have (wrt writes at most 18)."""
MAX_IMAGE_BYTES = 1 << 40
"""Largest image file read (bytes); its pixel count is bounded by ``MAX_IMAGE_SIDE`` too."""
_INT32 = np.iinfo(np.int32)


@dataclass(frozen=True)
class ImageData:
    """An image read back by `read_image`.

    Attributes
    ----------
    rgb : np.ndarray
        (H, W, 3) float32 linear radiance; a PNG is decoded from sRGB back to linear.
    aovs : dict of str to np.ndarray
        AOVs present in the file, keyed as in `AOV_CHANNELS`: ``depth`` and ``id`` are
        (H, W), ``normal`` and ``position`` (H, W, 3); float32 except ``id`` (int32).
    metadata : dict of str to str, int or float
        The ``wrt:`` attributes with the prefix removed. EXR keeps the type (floats as
        float32); PNG keeps text only, so every value comes back as str.
    """

    rgb: np.ndarray
    aovs: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)


def srgb_encode(rgb):
    """Apply the sRGB transfer curve to linear values.

    Parameters
    ----------
    rgb : array_like
        Linear values, any shape. NaN and values below 0 map to 0, values above 1
        (including +inf) to 1.

    Returns
    -------
    np.ndarray
        float64 encoded values in [0, 1], same shape.

    Notes
    -----
    ``12.92 x`` for ``x <= 0.0031308``, else ``1.055 x^(1/2.4) - 0.055``. No exposure change.

    References
    ----------
    IEC 61966-2-1:1999, Multimedia systems and equipment - Colour measurement and
    management - Part 2-1: Default RGB colour space - sRGB.
    """
    x = np.clip(np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1.0 / 2.4) - 0.055)


def srgb_decode(encoded):
    """Invert `srgb_encode`: sRGB-encoded values in [0, 1] to linear values.

    Parameters
    ----------
    encoded : array_like
        Encoded values in [0, 1], any shape.

    Returns
    -------
    np.ndarray
        float64 linear values in [0, 1], same shape.

    Notes
    -----
    ``y / 12.92`` for ``y <= 0.04045``, else ``((y + 0.055) / 1.055)^2.4`` (IEC 61966-2-1).
    """
    y = np.asarray(encoded, dtype=np.float64)
    return np.where(y <= 0.04045, y / 12.92, ((y + 0.055) / 1.055) ** 2.4)


def tonemap_srgb(rgb):
    """Tone-map linear radiance to 8-bit sRGB for display.

    Parameters
    ----------
    rgb : array_like
        (H, W, 3) linear radiance.

    Returns
    -------
    np.ndarray
        (H, W, 3) uint8: ``round(255 * srgb_encode(rgb))``; NaN gives 0.
    """
    return np.rint(255.0 * srgb_encode(rgb)).astype(np.uint8)


def write_image(path, rgb, *, aovs=None, metadata=None, half=False):
    """Write an image atomically; the format follows the extension.

    Parameters
    ----------
    path : str or os.PathLike
        Target file ending in ``.exr`` or ``.png`` (any case). Its folder must exist.
    rgb : array_like
        (H, W, 3) floating-point linear radiance; non-finite values are allowed in EXR.
    aovs : dict of str to array_like, optional
        AOVs keyed as in `AOV_CHANNELS`, each (H, W) or (H, W, 3) to match; ``id`` must be
        an integer array with magnitudes up to 2**24. EXR only.
    metadata : dict of str to str, int or float, optional
        Written as header attributes named ``wrt:<key>``; ints must fit in int32 and
        floats are stored as float32. PNG stores them as text.
    half : bool, optional
        Store ``R``, ``G``, ``B`` as half floats in EXR; AOVs stay float32. Values beyond
        ``HALF_MAX`` in magnitude (+-Inf included) are stored as +-``HALF_MAX`` (`half_overflow`
        counts them), so no Inf is written.

    Raises
    ------
    ValueError
        If `rgb`, `aovs` or `metadata` have the wrong names, types or shapes.
    WrtError
        If the extension is unsupported, AOVs are given for a PNG, the folder does not
        exist, or the file cannot be written completely (a full disk, a read-only folder);
        the previous file is then left as it was.
    """
    path = os.fspath(path)
    ext = _extension(path)
    rgb = _checked_rgb(rgb)
    aovs = _checked_aovs(aovs or {}, rgb.shape[:2])
    metadata = _checked_metadata(metadata or {})
    if ext == ".png":
        if aovs:
            raise WrtError(f"{path}: AOVs need an .exr output")
        spec, pixels = _png_spec_and_pixels(rgb, metadata)
    else:
        spec, pixels = _exr_spec_and_pixels(rgb, aovs, metadata, half)
    _write_atomically(path, ext, spec, pixels, half_channels=3 if half and ext == ".exr" else 0)


def write_srgb_png(path, pixels):
    """Write 8-bit sRGB pixels as they are to a PNG, atomically and checked like `write_image`.

    Parameters
    ----------
    path : str or os.PathLike
        Target file ending in ``.png`` (any case). Its folder must exist.
    pixels : array_like
        (H, W, 3) uint8 sRGB-encoded values (a screenshot, say), row 0 at the top.
    """
    path = os.fspath(path)
    if _extension(path) != ".png":
        raise WrtError(f"{path}: 8-bit sRGB pixels are written as .png")
    pixels = np.ascontiguousarray(pixels)
    if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.dtype != np.uint8 or 0 in pixels.shape:
        raise ValueError(f"pixels must be a non-empty (H, W, 3) uint8 array, got {pixels.shape} {pixels.dtype}")
    height, width, _ = pixels.shape
    _write_atomically(path, ".png", oiio.ImageSpec(width, height, 3, "uint8"), pixels)


def half_overflow(rgb) -> int:
    """How many values of ``rgb`` a half-float EXR (``write_image(..., half=True)``) stores as
    +-``HALF_MAX`` because they are larger in magnitude (Inf included)."""
    return int(np.count_nonzero(np.abs(np.asarray(rgb)) > HALF_MAX))


def read_image(path):
    """Read an image written by `write_image` (or any RGB ``.exr`` / ``.png``).

    Parameters
    ----------
    path : str or os.PathLike
        File ending in ``.exr`` or ``.png`` (any case).

    Returns
    -------
    ImageData
        Linear radiance, the AOVs found (by their `AOV_CHANNELS` names) and the ``wrt:``
        metadata.

    Raises
    ------
    WrtError
        If the file is missing, not a regular file, has an unsupported extension, is corrupt or
        truncated, is larger than ``MAX_IMAGE_SIDE`` pixels a side or has more than
        ``MAX_CHANNELS`` channels (checked before its pixels are allocated), or lacks the ``R``,
        ``G``, ``B`` channels or part of an AOV's channels.
    """
    path = os.fspath(path)
    ext = _extension(path)
    spec, pixels = read_pixels(path, "image", format="uint8" if ext == ".png" else "float")
    metadata = {
        a.name[len(METADATA_PREFIX) :]: a.value for a in spec.extra_attribs if a.name.startswith(METADATA_PREFIX)
    }
    if ext == ".png":
        if spec.nchannels < 3:
            raise WrtError(f"{path}: expected an RGB image, found {spec.nchannels} channel(s)")
        rgb = srgb_decode(pixels[..., :3] / 255.0).astype(np.float32)
        return ImageData(rgb=rgb, metadata=metadata)
    channels = {name: pixels[..., c] for c, name in enumerate(spec.channelnames)}
    return ImageData(
        rgb=_stacked(path, channels, _RGB_CHANNELS),
        aovs=_aovs_from_channels(path, channels),
        metadata=metadata,
    )


@contextlib.contextmanager
def _native_stderr_quiet():
    """Within: what native libraries print to file descriptor 2 is dropped. libpng writes "libpng
    error: ..." there itself before OpenImageIO reports the same error, which wrt then prints as
    its one line."""
    with _STDERR_LOCK, tempfile.TemporaryFile() as sink:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)


_STDERR_LOCK = threading.Lock()


def read_pixels(
    path, what: str, *, error: type[WrtError] = WrtError, format: str = "float", max_pixels: int | None = None
):
    """``(ImageSpec, pixels)`` of the image file ``path``: its pixels (H, W, C) as ``format``
    ("float" or "uint8"), read by OpenImageIO once the file is known to be a regular file (a FIFO
    would block) of a size wrt reads: at most ``MAX_IMAGE_SIDE`` pixels a side (and
    ``max_pixels`` in all), ``MAX_CHANNELS`` channels, refused before any pixel is allocated.
    ``error`` naming ``path`` and ``what`` it is otherwise, or when OpenImageIO cannot read it (its
    message cut short, and nothing of libpng's own on stderr)."""
    path = os.fspath(path)
    check_regular_file(path, what, limit=MAX_IMAGE_BYTES, error=error)
    with _native_stderr_quiet():
        inp = oiio.ImageInput.open(path)
        if inp is None:
            raise error(f"{path}: cannot read {what}: {_oiio_error(oiio.geterror())}")
        try:
            spec = inp.spec()
            if max(spec.width, spec.height) > MAX_IMAGE_SIDE or spec.nchannels > MAX_CHANNELS or spec.depth > 1:
                raise error(
                    f"{path}: {what} of {spec.width} x {spec.height} pixels, {spec.nchannels} channels: wrt reads at "
                    f"most {MAX_IMAGE_SIDE} pixels a side and {MAX_CHANNELS} channels"
                )
            if max_pixels is not None and spec.width * spec.height > max_pixels:
                raise error(f"{path}: {what} of {spec.width} x {spec.height} pixels, more than {max_pixels}")
            try:
                pixels = inp.read_image(0, 0, 0, spec.nchannels, format)
            except MemoryError:
                raise error(
                    f"{path}: {what} of {spec.width} x {spec.height} pixels, {spec.nchannels} channels: not enough "
                    "memory to read it"
                ) from None
            if pixels is None:
                raise error(f"{path}: cannot read {what}: {_oiio_error(inp.geterror())}")
        finally:
            inp.close()
    return spec, np.asarray(pixels).reshape(spec.height, spec.width, spec.nchannels)


def _oiio_error(message: str) -> str:
    """OpenImageIO's error message as one of wrt's (``wrt.errors.foreign``: its first line, what
    it quotes of the file cut short)."""
    return foreign(message) if message.strip() else "unknown error"


def _extension(path):
    """Return the lower-case extension of `path`, raising WrtError if it is unsupported."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise WrtError(f"{path}: unsupported image extension {ext!r}; use one of " + ", ".join(SUPPORTED_EXTENSIONS))
    return ext


def _checked_rgb(rgb):
    """Return `rgb` as an array, raising ValueError unless it is (H, W, 3) floating point."""
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.shape[0] == 0 or rgb.shape[1] == 0:
        raise ValueError(f"rgb must have shape (H, W, 3) with H, W > 0, got {rgb.shape}")
    if not np.issubdtype(rgb.dtype, np.floating):
        raise ValueError(f"rgb must be a floating-point array, got dtype {rgb.dtype}")
    return rgb


def _checked_aovs(aovs, size):
    """Return `aovs` as arrays, raising ValueError on unknown names, shapes or id dtype/range."""
    checked = {}
    for name, values in aovs.items():
        if name not in AOV_CHANNELS:
            raise ValueError(f"unknown AOV {name!r}; known AOVs are {', '.join(AOV_CHANNELS)}")
        values = np.asarray(values)
        n = len(AOV_CHANNELS[name])
        expected = size if n == 1 else (*size, n)
        if values.shape != expected:
            raise ValueError(f"AOV {name!r} must have shape {expected}, got {values.shape}")
        if name == "object_id":
            if not np.issubdtype(values.dtype, np.integer):
                raise ValueError(f"AOV 'object_id' must be an integer array, got dtype {values.dtype}")
            if np.abs(values.astype(np.int64)).max() > _MAX_EXACT_ID:
                raise ValueError("AOV 'object_id' values must lie in [-2**24, 2**24] (exact in float32)")
        elif not np.issubdtype(values.dtype, np.floating):
            raise ValueError(f"AOV {name!r} must be a floating-point array, got {values.dtype}")
        checked[name] = values
    return checked


def _checked_metadata(metadata):
    """Return `metadata` unchanged, raising ValueError on keys or values it cannot store."""
    for key, value in metadata.items():
        if not isinstance(key, str) or not key:
            raise ValueError(f"metadata keys must be non-empty strings, got {key!r}")
        if isinstance(value, bool) or not isinstance(value, (str, int, float)):
            raise ValueError(f"metadata {key!r} must be a str, int or float, got {value!r}")
        if isinstance(value, int) and not _INT32.min <= value <= _INT32.max:
            raise ValueError(f"metadata {key!r} = {value} does not fit in int32")
    return metadata


def _exr_spec_and_pixels(rgb, aovs, metadata, half):
    """Return the OIIO spec and the (H, W, C) float32 pixels of an EXR with AOVs and metadata;
    ``half``: R, G, B as half floats, clamped to +-``HALF_MAX``."""
    names = list(_RGB_CHANNELS)
    planes = [np.clip(rgb, -HALF_MAX, HALF_MAX).astype(np.float32) if half else rgb.astype(np.float32)]
    for name, values in aovs.items():
        names += AOV_CHANNELS[name]
        planes.append(values.astype(np.float32).reshape(*values.shape[:2], -1))
    pixels = np.ascontiguousarray(np.concatenate(planes, axis=2))
    height, width, nchannels = pixels.shape
    spec = oiio.ImageSpec(width, height, nchannels, "half" if half and nchannels == 3 else "float")
    spec.channelnames = tuple(names)
    if half and nchannels > 3:  # per-channel formats apply only where they differ
        spec.channelformats = (oiio.TypeDesc("half"),) * 3 + (oiio.TypeDesc("float"),) * (nchannels - 3)
    for key, value in metadata.items():
        spec.attribute(METADATA_PREFIX + key, value)
    return spec, pixels


def _png_spec_and_pixels(rgb, metadata):
    """Return the OIIO spec and the (H, W, 3) uint8 sRGB pixels of a PNG with text metadata."""
    pixels = tonemap_srgb(rgb)
    height, width, _ = pixels.shape
    spec = oiio.ImageSpec(width, height, 3, "uint8")
    for key, value in metadata.items():
        spec.attribute(METADATA_PREFIX + key, str(value))
    return spec, pixels


def _write_atomically(path, ext, spec, pixels, half_channels=0):
    """Write `pixels` to a temporary file beside `path`, read it back, and move it over `path`
    (``wrt.files.atomic_path``) only if it holds exactly `pixels` (the first `half_channels`
    rounded to half floats): on any failure, KeyboardInterrupt included, `path` is left as it was."""
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise WrtError(f"{path}: folder {folder} does not exist")
    expected = pixels
    if half_channels:
        expected = pixels.copy()
        expected[..., :half_channels] = pixels[..., :half_channels].astype(np.float16)

    def verify(tmp):
        try:
            stored, written = read_pixels(tmp, "image", format="uint8" if ext == ".png" else "float")
        except WrtError:
            written = None
        else:
            names = list(stored.channelnames)  # EXR stores channels in its own order
            if sorted(names) == sorted(spec.channelnames):
                written = written[..., [names.index(n) for n in spec.channelnames]]
        if written is None or written.shape != expected.shape or not np.array_equal(written, expected, equal_nan=True):
            raise WrtError(
                f"{path}: cannot write image: the file written is incomplete (is the disk full?); the file was left "
                "as it was"
            )

    with atomic_path(path, suffix=ext, verify=verify) as tmp:
        out = oiio.ImageOutput.create(tmp)
        if out is None:
            raise WrtError(f"{path}: cannot write image: {_oiio_error(oiio.geterror())}")
        ok = out.open(tmp, spec) and out.write_image(pixels)
        error = out.geterror()
        ok = out.close() and ok
        if not ok:
            raise WrtError(
                f"{path}: cannot write image: {_oiio_error(error or out.geterror())}; the file was left as it was"
            )


def _stacked(path, channels, names):
    """Stack the named float channels into (H, W, len(names)) float32, or raise WrtError."""
    missing = [n for n in names if n not in channels]
    if missing:
        raise WrtError(f"{path}: missing channel(s) {', '.join(missing)}")
    return np.stack([channels[n] for n in names], axis=2).astype(np.float32)


def _aovs_from_channels(path, channels):
    """Return the AOVs whose channels are present, raising WrtError for a partial set."""
    aovs = {}
    for name, names in AOV_CHANNELS.items():
        if not any(n in channels for n in names):
            continue
        values = _stacked(path, channels, names)
        if len(names) == 1:
            values = values[..., 0]
        aovs[name] = values.astype(np.int32) if name == "object_id" else values
    return aovs
