"""The bounds wrt puts on what it is asked to do, in one light module (no imports): the loader,
the Mitsuba importer, the image reader and the command line check against the same numbers."""

MAX_IMAGE_SIDE = 16384
"""Largest image width or height in pixels, rendered or read."""
MAX_SPP = 1 << 20
"""Most samples per pixel."""
MAX_DEPTH = 1024
"""Most ray segments of a path (``max_depth``); what Mitsuba's ``max_depth = -1`` (unbounded) becomes."""
MAX_SEED = 2**31 - 1
"""Largest random seed."""
MAX_MAGNITUDE = 1e18
"""Largest magnitude of any number of a scene (coordinates, lengths, radiances, shutter times) and
of a shape's displacement over the shutter (``|velocity| * max(|open|, |close|)``). The kernels
compute in float32 (largest finite value about 3.4e38): squared distances between points within
this bound (at most 3 * (2e18)^2 = 1.2e37) and a radiance summed over 2^20 samples (1e24) stay
finite, with a factor of 28 to spare. Larger numbers are refused rather than rendered as Inf or NaN."""
