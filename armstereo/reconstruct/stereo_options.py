"""Options of the two matchers, each a frozen dataclass validated once when it is made.

:class:`BirchfieldOptions` (the paper's matcher, :func:`armstereo.reconstruct.stereo.birchfield`)
and :class:`SgbmOptions` (OpenCV's StereoSGBM as a peer, :func:`.sgbm.sgbm`). An options object
names its matcher (``options.method``), so one object says how a pair is matched from the
library (``reconstruct_views(..., stereo=...)``) to the command line and the reports, which
record it whole (:meth:`BirchfieldOptions.as_dict`). Fields whose metadata carries a flag
(:func:`armstereo.flags.option`) are the ``armstereo stereo`` / ``reconstruct`` command-line
flags (:mod:`armstereo.cli.matcher_flags` builds them from here).

The defaults were chosen by measurement; why each differs from the paper (which
:meth:`BirchfieldOptions.paper` restores) is docs/birchfield-tomasi.md, "Defaults and why".
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from armstereo import validate
from armstereo.errors import StereoError
from armstereo.flags import option

METHODS = ("birchfield", "sgbm")
COLOR_MODES = ("gray", "sum", "max")
SUBPIXEL_MODES = ("fast", "none", "parabola", "gradient")
SEARCH_MODES = ("exact", "pruned")
OCCLUSION_MODES = ("nan", "fill")
POSTPROCESS_MODES = ("median", "paper", "none")
PREFILTER_MODES = ("none", "highpass", "edges")
SGBM_MODES = ("sgbm", "hh", "3way", "hh4")  # OpenCV's STEREO_SGBM_MODE_*
# SGBM's sub-pixel steps (SgbmOptions; measured on the realistic cell: bench/results/sgbm_desk.md)
SGBM_PRESMOOTH, SGBM_SHIFTS = 0.0, 1  # px (Gaussian sigma); matches averaged
SGBM_MAX_PRESMOOTH, SGBM_MAX_SHIFTS = 10.0, 16

# Defaults chosen on the benchmarks (docs/birchfield-tomasi.md, "Defaults and why")
OCCLUSION_PENALTY = 25.0  # grey levels (the paper's)
COST_WINDOW = (1, 3)  # (width, height) of the summed-cost window
SLANT_PENALTY = 20.0  # grey levels, for a one-pixel disparity step
TEXTURE_THRESHOLD = 1.0  # grey levels per pixel, mean |horizontal gradient| over the window
REWARD_TEXTURE = 0.5  # grey levels per pixel: matching flatter pixels earns no reward
MATCH_REWARD = 6.0  # grey levels (the paper's 5 on intensities; 5.5, 6.5 measured)
PREFILTER = "edges"
# grey levels: "edges" adds the horizontal Sobel clipped to +-this (10, 12, 15, 20 measured:
# bench/results/stereo_accuracy.md)
EDGE_CAP = 12.0
PREFILTER_SIGMA = 8.0  # px: slower brightness changes than this are removed
PREFILTER_GAIN = 2.0  # contrast of what is left (the penalties are in grey levels)
# local normalisation (bench/results/radiometric.md): window side (px), noise floor and
# contrast of the result (grey levels)
NORMALIZE_WINDOW = 0  # off: equalize instead (7 is the equalisation's first pass)
NORMALIZE_FLOOR = 4.0
NORMALIZE_SCALE = 24.0
PLAIN_FILL = 0.5  # share of a plain run the programme must support to be filled
SPECKLE_SIZE = 100  # pixels
SPECKLE_RANGE = 2.0  # pixels of disparity
CONSENSUS_SIZE = 9  # pixels: side of the consensus median's square
OCCLUSION_MARGIN = 5.0  # pixels: see rejection.hidden_by_nearer (1, 2, 3, 5, 8 measured)
SUBPIXEL_RADIUS = 5  # "gradient"/"parabola" sub-pixel steps: window 2 r + 1
# photo_check for photometrically clean views (noise ~1 grey level, same exposure and
# response in both), chosen on the mock table scene (bench/results/footprint.md)
CLEAN_PHOTO_CHECK = 4.0

# The paper's matcher as published (single-pixel costs, its postprocessing, nothing added):
# ``birchfield(left, right, n, **PAPER_OPTIONS)`` or ``BirchfieldOptions.paper()``
PAPER_OPTIONS = dict(cost_window=(1, 1), slant_penalty=None, postprocess="paper",
                     texture_threshold=0.0, reward_texture=0.0, speckle_size=0,
                     subpixel="none", occlusions="fill", column_support=False,
                     consensus_size=0, prefilter="none", match_reward=5, normalize_window=0,
                     equalize=False, plain_fill=None, censor_saturated=False)


def _grey_levels(text: str) -> float:
    """Command-line value of a grey-level threshold: 0..255."""
    return validate.non_negative(text, "value", "grey levels", cap=255.0)


def _thread_count(text: str) -> int:
    """Command-line value of a thread count: 1..256."""
    return validate.whole(text, "value", 1, 256)


_PHOTO_CHECK_HELP = ("near depth jumps, drop matches whose views differ by more than G grey "
                     "levels (against foreground fattening; for clean, evenly lit images; about "
                     "4; default 0 = off)")


@dataclass(frozen=True, kw_only=True)
class BirchfieldOptions:
    """How :func:`armstereo.reconstruct.stereo.birchfield` matches (grey-level units).

    The algorithm: the sampling-insensitive symmetric dissimilarity, one dynamic programme per
    scanline over match sequences (an occlusion costs ``occlusion_penalty`` once, each match
    earns ``match_reward``, occlusions only next to intensity variation), then postprocessing.
    :meth:`paper` gives the paper's plain matcher; the defaults add (why:
    docs/birchfield-tomasi.md):

    - ``cost_window`` ``(width, height)``: node costs are dissimilarities summed over this
      window at the same disparity (penalties scale with it); ``(1, 1)`` is the paper's.
      Summing over rows ties neighbouring scanlines together (no streaks). Odd sides.
    - ``slant_penalty``: a one-pixel disparity step costs this instead of an occlusion and
      needs no intensity variation (slanted surfaces); None = the paper's model.
    - ``texture_threshold``: a pixel is flat where the mean absolute horizontal gradient over
      a 5x5 window is below this (grey levels per pixel); a flat pixel keeps its disparity
      only if the nearest textured pixels left and right of it on the row agree with it
      (:func:`.rejection.unsupported`), else NaN: no invented depth on backgrounds and gaps.
      0 = off.
    - ``plain_fill``: a run of flat pixels (along a row, then a column) whose textured ends
      agree gets the straight line between them where it has no answer, when at least this
      share of the run's answers supported that surface (:mod:`.plain`): a plain table top
      between textured objects gets the table's surface; a background that the programme
      saw elsewhere stays empty. Needs ``texture_threshold`` > 0. None = off.
    - ``reward_texture``: matching a left pixel flatter than this earns no ``match_reward``,
      so the programme gains nothing by matching featureless pixels. 0 = reward everywhere.
    - ``column_support``: a flat pixel its row does not confirm is still kept when the
      nearest textured pixels above and below it in its column confirm it (the same test
      along the column); False = rows only.
    - ``consensus_size``: an answer differing by more than ``speckle_range`` from the median
      answer over this square around it is replaced by that median
      (:func:`.consensus.replace_outliers`); 0 = off. Odd, >= 3.
    - ``column_smoothing``: ``(p1, p2)``: the programme's node costs are first smoothed
      along each column, down and up, as semi-global matching does along one line (a
      one-disparity change between rows costs ``p1``, a larger one ``p2``), and each row's
      programme runs on the sum (replaces ``cost_window``'s summing; one thread, an (H, W,
      disparities) float32 volume). Needs ``color="gray"`` and ``search="exact"``. None = off.
    - ``speckle_size``/``speckle_range``: NaN on connected regions of fewer than
      ``speckle_size`` pixels whose disparity differs by more than ``speckle_range`` pixels
      from their surroundings (OpenCV's ``filterSpeckles``, as SGBM does); 0 = off.
    - ``postprocess``: ``"median"`` (True): 5x5 median of the sub-pixel map; ``"paper"``: the
      paper's propagation across scanlines, mode filters; ``"none"`` (False). Stored by name.
    - ``subpixel``: ``"fast"``: one Lucas-Kanade step over a 5x5 window, each pixel at its own
      disparity (:func:`.subpixel.gradient_step`); ``"gradient"`` (iterated, over a window of
      the same surface) or ``"parabola"`` (windowed SSD at d-1, d, d+1), both with a
      ``2 * subpixel_radius + 1`` window; ``"none"``.
    - ``search``: ``"exact"`` solves each scanline's programme exactly (O(width x
      disparities)); ``"pruned"``: the reference code's heuristic search (18x slower).
    - ``color``: ``"gray"`` matches the BGR2GRAY image; ``"sum"``/``"max"`` combine
      per-channel dissimilarities. ``"pruned"``, ``"sum"`` and ``"max"`` run the paper's
      single-pixel kernels: ``cost_window`` and ``slant_penalty`` do not apply.
    - ``occlusions``: ``"nan"`` leaves NaN on left pixels the final map itself shows hidden by
      a nearer pixel (their right-image position at least ``occlusion_margin`` pixels right
      of that of a pixel right of them, :func:`.rejection.hidden_by_nearer`); ``"fill"`` keeps
      the paper's background fill.
    - ``lr_check``: also match right-to-left (mirrored pair), reject disparities differing
      by more than one pixel (twice the time).
    - ``threads``: the steps run on this many threads (None: ``numba.get_num_threads()``),
      on chunks or strips of rows; the result does not depend on it (a second thread: 1.5-1.9x
      at 0.3-1.5 megapixels, much less on small images, bench/results/stereo_scaling.md).
    - ``censor_saturated``: a pixel with a channel at 255 (0) was at least (at most) that
      bright: its dissimilarity interval is opened on that side (:mod:`.saturation`). Grey.
    - ``prefilter``: ``"edges"`` matches ``I + clip(Sobel_x(I), -edge_cap, edge_cap)`` of
      each grey image (3x3 horizontal Sobel, saturated to uint8; :func:`.stereo_inputs.with_edges`):
      the dissimilarity then also compares the images' horizontal gradients, as SGBM's
      prefiltered cost does, so depth jumps land on the objects' outlines instead of carrying
      the nearer surface past them. ``"highpass"`` matches ``prefilter_gain * (I - G * I) +
      128`` of each grey image (``G``: a Gaussian of ``prefilter_sigma`` px, normalised over
      the valid pixels), so brightness that changes slowly across the image (vignetting,
      exposure) does not shift matches; ``"none"`` matches the intensities as the paper does.
      Grey matching only: ``"edges"`` does not apply to ``color="sum"``/``"max"``,
      ``"highpass"`` is refused there.
    - ``equalize``: before matching, the right grey image is given the left one's
      brightness: a quick brightness-blind first pass at half size finds matching pixels,
      and a gamma and a smooth gain field fitted to them are removed from the right image
      (:mod:`.equalize`): a gain, gamma, vignetting or lighting difference between the views
      (a real arm takes them at different times from different places) no longer shifts or
      loses matches, while the intensities, shading included, are still what is compared.
      Grey matching only (colour costs compare the colour images as they are). False = the
      paper's plain intensities.
    - ``normalize_window``: before the prefilter, each grey image becomes ``128 +
      normalize_scale * (I - mean) / (std + normalize_floor)`` over this odd square of valid
      pixels (:mod:`.normalize`), so the programme and the sub-pixel steps compare local
      structure, not brightness, even where the light changes within a few pixels; it also
      removes the shading that guides the programme on plain smooth surfaces, so it costs
      accuracy where ``equalize`` suffices (bench/results/radiometric.md). The texture maps
      and the photo-consistency check read the grey images. 0 = off (default). Grey
      matching only.
    - ``photo_check``: NaN where the final match does not look alike: the grey difference
      ``|L(x) - R(x - d(x))|`` (right image interpolated, each pixel at its own disparity, so
      a window at a depth edge compares each surface with itself) averaged over the 3x3
      answered pixels around it exceeds this many grey levels
      (:func:`.rejection.photo_inconsistent`). Only pixels within 16 px along the row of a
      disparity jump of more than 2 px are tested: it removes the foreground carried across a
      half-occluded strip or a steep side, which no disparity test can tell from the
      foreground. Only for photometrically clean views (:data:`CLEAN_PHOTO_CHECK`): real
      photographs differ by as much at correct matches. 0 = off (default).

    Raises StereoError for a value out of range (the messages name the option).
    """

    method: ClassVar[str] = "birchfield"

    occlusion_penalty: float = OCCLUSION_PENALTY
    match_reward: float = MATCH_REWARD
    color: str = field(default="gray", metadata=option(
        "--color", "grey matching (default) or per-channel costs summed / maximum",
        choices=COLOR_MODES))
    postprocess: bool | str = field(default="median", metadata=option(
        "--no-postprocess", "raw scanline result, without the paper's propagation across rows",
        action="store_const", const="none"))
    occlusions: str = field(default="nan", metadata=option(
        "--occlusions", "nan: no disparity where a nearer surface hides the pixel (default); "
        "fill: the paper's background fill", choices=OCCLUSION_MODES))
    lr_check: bool = field(default=False, metadata=option(
        "--lr-check", "reject pixels failing a left-right consistency check (twice the time)",
        action="store_true"))
    subpixel: str = field(default="fast", metadata=option(
        "--subpixel", "subpixel refinement (default fast)", choices=SUBPIXEL_MODES))
    subpixel_radius: int = SUBPIXEL_RADIUS
    search: str = "exact"
    threads: int | None = field(default=None, metadata=option(
        "--threads", "match and filter on K threads (default: all cores; same map)",
        type=_thread_count, metavar="K"))
    cost_window: tuple[int, int] = COST_WINDOW
    slant_penalty: float | None = SLANT_PENALTY
    texture_threshold: float = TEXTURE_THRESHOLD
    speckle_size: int = SPECKLE_SIZE
    speckle_range: float = SPECKLE_RANGE
    reward_texture: float = REWARD_TEXTURE
    prefilter: str = PREFILTER
    prefilter_sigma: float = PREFILTER_SIGMA
    prefilter_gain: float = PREFILTER_GAIN
    edge_cap: float = EDGE_CAP
    equalize: bool = True
    censor_saturated: bool = True
    normalize_window: int = NORMALIZE_WINDOW
    normalize_floor: float = NORMALIZE_FLOOR
    normalize_scale: float = NORMALIZE_SCALE
    occlusion_margin: float = OCCLUSION_MARGIN
    photo_check: float = field(default=0.0, metadata=option(
        "--photo-check", _PHOTO_CHECK_HELP, type=_grey_levels, metavar="G"))
    column_support: bool = True
    plain_fill: float | None = PLAIN_FILL
    consensus_size: int = CONSENSUS_SIZE
    column_smoothing: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen: the normalised forms are set once, here
        set_(self, "postprocess", _postprocess_mode(self.postprocess))
        for name, allowed in (("color", COLOR_MODES), ("subpixel", SUBPIXEL_MODES),
                              ("search", SEARCH_MODES), ("occlusions", OCCLUSION_MODES),
                              ("postprocess", POSTPROCESS_MODES)):
            value = getattr(self, name)
            if value not in allowed:
                raise StereoError(f"{name}={value!r} is not one of {', '.join(allowed)}")
        if self.threads is not None and self.threads < 1:
            raise StereoError(f"threads must be >= 1, got {self.threads}")
        if not (self.occlusion_penalty >= 0 and self.match_reward >= 0
                and self.subpixel_radius >= 0):
            raise StereoError(f"occlusion_penalty ({self.occlusion_penalty}), match_reward "
                              f"({self.match_reward}) and subpixel_radius "
                              f"({self.subpixel_radius}) must be >= 0")
        set_(self, "cost_window", _window(self.cost_window))
        self._check_rejections()
        set_(self, "column_smoothing", _smoothing(self.column_smoothing))
        if self.column_smoothing is not None and (self.color != "gray"
                                                  or self.search != "exact"):
            raise StereoError('column_smoothing needs color="gray" and search="exact"')
        self._check_prefilter()

    def _check_rejections(self) -> None:
        if self.slant_penalty is not None and not self.slant_penalty >= 0:
            raise StereoError(f"slant_penalty must be >= 0 or None, got {self.slant_penalty}")
        if not (self.texture_threshold >= 0 and self.speckle_size >= 0
                and self.speckle_range >= 0):  # NaN too
            raise StereoError(f"texture_threshold ({self.texture_threshold}), speckle_size "
                              f"({self.speckle_size}) and speckle_range ({self.speckle_range})"
                              " must be >= 0")
        size = self.consensus_size
        if size != 0 and (size < 3 or size % 2 == 0):
            raise StereoError(f"consensus_size must be 0 (off) or odd and >= 3, got {size}")
        if not self.occlusion_margin >= 0:
            raise StereoError(f"occlusion_margin must be >= 0 pixels, got "
                              f"{self.occlusion_margin}")
        if self.plain_fill is not None and not 0 <= self.plain_fill <= 1:
            raise StereoError(f"plain_fill must be a share 0..1 or None, got {self.plain_fill}")
        if not self.photo_check >= 0:
            raise StereoError(f"photo_check must be >= 0 grey levels, got {self.photo_check}")

    def _check_prefilter(self) -> None:
        if self.prefilter not in PREFILTER_MODES:
            raise StereoError(f"prefilter={self.prefilter!r} is not one of "
                              f"{', '.join(PREFILTER_MODES)}")
        if self.prefilter == "highpass":
            if self.color != "gray":
                raise StereoError('prefilter="highpass" works on grey matching only '
                                  '(color="gray")')
            if not (self.prefilter_sigma > 0 and self.prefilter_gain > 0):
                raise StereoError(f"prefilter_sigma ({self.prefilter_sigma}) and "
                                  f"prefilter_gain ({self.prefilter_gain}) must be > 0")
        if self.prefilter == "edges" and not self.edge_cap > 0:
            raise StereoError(f"edge_cap must be > 0 grey levels, got {self.edge_cap}")
        w = self.normalize_window
        if isinstance(w, bool) or not isinstance(w, int | np.integer) or (
                w != 0 and (w < 3 or w % 2 == 0)):
            raise StereoError(f"normalize_window must be 0 (off) or odd and >= 3, got {w!r}")
        if w and not (self.normalize_floor > 0 and self.normalize_scale > 0):
            raise StereoError(f"normalize_floor ({self.normalize_floor}) and normalize_scale "
                              f"({self.normalize_scale}) must be > 0 grey levels")

    @classmethod
    def paper(cls, **changes: Any) -> BirchfieldOptions:
        """The paper's matcher as published (:data:`PAPER_OPTIONS`), with ``changes``."""
        return cls(**{**PAPER_OPTIONS, **changes})

    @property
    def normalization(self) -> tuple[int, float, float] | None:
        """``(window, floor, scale)`` of the local normalisation, None when it is off."""
        if not self.normalize_window:
            return None
        return self.normalize_window, self.normalize_floor, self.normalize_scale

    @property
    def single_pixel(self) -> bool:
        """True when the paper's single-pixel kernels run (colour costs or the pruned
        search), where ``cost_window`` and ``slant_penalty`` do not apply."""
        return self.color != "gray" or self.search != "exact"

    def as_dict(self) -> dict[str, Any]:
        """Every option by name, JSON-ready (tuples as lists): what the reports record."""
        return _as_dict(self)

    def non_defaults(self) -> dict[str, Any]:
        """The options that differ from the defaults, by name (values as stored)."""
        return _non_defaults(self)


@dataclass(frozen=True, kw_only=True)
class SgbmOptions:
    """How :func:`armstereo.reconstruct.sgbm.sgbm` (OpenCV StereoSGBM) matches.

    ``block_size`` (odd, px), ``uniqueness`` (percent), ``speckle_window`` (pixels, 0 = no
    speckle filter), ``speckle_range`` (disparity), ``lr_tolerance`` (pixels of left-right
    difference, negative = no check): OpenCV's ``blockSize``, ``uniquenessRatio``,
    ``speckleWindowSize``, ``speckleRange`` and ``disp12MaxDiff``. ``mode``: OpenCV's
    ``mode`` (:data:`SGBM_MODES`: "sgbm" 5 paths, "hh" 8 paths, "3way", "hh4").

    Two sub-pixel steps around OpenCV's parabola, which locks answers to whole disparities
    (half the answers within 1/8 px of a whole number on the demo's desk):

    - ``presmooth``: sigma (px) of a Gaussian blur of both images before matching, 0 = off;
      it takes sensor noise out and makes the cost curve smooth enough for the parabola.
    - ``shifts``: the mean of ``shifts`` matches with the right image moved by ``k / shifts``
      px (:func:`.sgbm.shift_averaged`: the parabola's periodic error cancels; Shimizu and
      Okutomi, ICCV 2001); same density, ``shifts`` times the time. 1 = OpenCV's answer.

    Defaults: bench/results/sgbm_desk.md. Raises StereoError for values OpenCV would refuse.
    """

    method: ClassVar[str] = "sgbm"

    block_size: int = 5
    uniqueness: int = 10
    speckle_window: int = 100
    speckle_range: int = 2
    lr_tolerance: int = 1
    mode: str = field(default="sgbm", metadata=option("--sgbm-mode", "OpenCV's SGBM mode: "
                      "sgbm (5 paths, default), hh (8), 3way, hh4", choices=SGBM_MODES))
    presmooth: float = field(default=SGBM_PRESMOOTH, metadata=option(
        "--sgbm-presmooth", "blur both images by a Gaussian of this sigma first (px; the demo "
        "uses 1; default 0 = off)", metavar="PX",
        type=lambda t: validate.non_negative(t, "value", "px", cap=SGBM_MAX_PRESMOOTH)))
    shifts: int = field(default=SGBM_SHIFTS, metadata=option(
        "--sgbm-shifts", "average the matches of N sub-pixel shifts of the right image (the "
        "demo uses 4; N times the time; default 1)", metavar="N",
        type=lambda t: validate.whole(t, "value", 1, SGBM_MAX_SHIFTS)))

    def __post_init__(self) -> None:
        for name in ("block_size", "uniqueness", "speckle_window", "speckle_range",
                     "lr_tolerance", "shifts"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise StereoError(f"SGBM {name} must be a whole number, got {value!r}")
        if self.block_size < 1 or self.block_size % 2 == 0:
            raise StereoError(f"SGBM block_size must be odd and >= 1, got {self.block_size}")
        for name in ("uniqueness", "speckle_window", "speckle_range"):
            if getattr(self, name) < 0:
                raise StereoError(f"SGBM {name} must be >= 0, got {getattr(self, name)}")
        if self.mode not in SGBM_MODES:
            raise StereoError(f"SGBM mode={self.mode!r} is not one of {', '.join(SGBM_MODES)}")
        if isinstance(self.presmooth, bool) or not isinstance(
                self.presmooth, int | float | np.integer | np.floating) or not (
                0 <= self.presmooth <= SGBM_MAX_PRESMOOTH):  # NaN too
            raise StereoError(f"SGBM presmooth must be 0..{SGBM_MAX_PRESMOOTH} px, got "
                              f"{self.presmooth!r}")
        if not 1 <= self.shifts <= SGBM_MAX_SHIFTS:
            raise StereoError(f"SGBM shifts must be 1..{SGBM_MAX_SHIFTS}, got {self.shifts}")

    def as_dict(self) -> dict[str, Any]:
        """Every option by name, JSON-ready: what the reports record."""
        return _as_dict(self)

    def non_defaults(self) -> dict[str, Any]:
        """The options that differ from the defaults, by name."""
        return _non_defaults(self)


StereoOptions = BirchfieldOptions | SgbmOptions
OPTIONS_TYPES: dict[str, type] = {"birchfield": BirchfieldOptions, "sgbm": SgbmOptions}


def options_for(method: str | None, given: StereoOptions | Mapping[str, Any] | None = None,
                *, error: type[Exception] = StereoError) -> StereoOptions:
    """The options object that says how to match: ``given`` itself (its type names the
    method), the defaults of ``method`` (None ``given``), or ``method``'s options made from
    the keywords in a mapping (the old ``stereo_options`` dicts). ``method`` None: from
    ``given``'s type, else ``"birchfield"``.

    Raises ``error`` for an unknown method or options of another method's type, TypeError
    for a keyword the method's options do not have.
    """
    if isinstance(given, BirchfieldOptions | SgbmOptions):
        if method is not None and method != given.method:
            raise error(f"method {method!r} does not take {type(given).__name__} "
                        f"(the options of {given.method})")
        return given
    method = "birchfield" if method is None else method
    if method not in OPTIONS_TYPES:
        raise error(f"unknown stereo method {method!r}; choose one of {', '.join(METHODS)}")
    return with_keywords(OPTIONS_TYPES[method](), dict(given or {}), method)


def resolve_matcher(method: str | None, stereo: StereoOptions | None = None,
                    stereo_options: Mapping[str, Any] | None = None, *,
                    error: type[Exception] = StereoError) -> StereoOptions:
    """The options of a caller that takes either an options object (``stereo``) or ``method``
    with the older dict of the matcher's keywords (``stereo_options``): :func:`options_for`,
    and ``error`` when both kinds are given."""
    if stereo is not None and stereo_options is not None:
        raise error("give stereo (an options object) or stereo_options, not both")
    return options_for(method, stereo if stereo is not None else stereo_options, error=error)


def matcher_record(options: StereoOptions | None) -> dict[str, Any] | None:
    """``{"method": ..., "options": {every field}}``: how a map was matched, as the reports
    and recordings keep it (None stays None, e.g. depth that was not matched)."""
    if options is None:
        return None
    return {"method": options.method, "options": options.as_dict()}


def with_keywords(options: StereoOptions, keywords: Mapping[str, Any],
                  caller: str) -> StereoOptions:
    """``options`` with the given fields changed (validated again); TypeError naming
    ``caller`` for a keyword that is not one of its fields."""
    if not keywords:
        return options
    names = {f.name for f in dataclasses.fields(options)}
    for name in keywords:
        if name not in names:
            raise TypeError(f"{caller}() got an unexpected keyword argument {name!r}")
    return dataclasses.replace(options, **keywords)


def _postprocess_mode(postprocess: bool | str) -> str:
    if postprocess is True:
        return "median"
    if postprocess is False:
        return "none"
    return postprocess


def _window(cost_window) -> tuple[int, int]:
    """``(width, height)`` of the summed-cost window, checked: odd sides >= 1."""
    try:
        w, h = (int(v) for v in cost_window)
    except (TypeError, ValueError):
        raise StereoError(f"cost_window must be (width, height), got {cost_window!r}") from None
    if w < 1 or h < 1 or w % 2 == 0 or h % 2 == 0:
        raise StereoError(f"cost_window sides must be odd and >= 1, got {cost_window!r}")
    return w, h


def _smoothing(column_smoothing) -> tuple[float, float] | None:
    """``(p1, p2)`` grey levels of the column pass, checked (None = off)."""
    if column_smoothing is None:
        return None
    try:
        p1, p2 = (float(v) for v in column_smoothing)
    except (TypeError, ValueError):
        raise StereoError(f"column_smoothing must be (p1, p2) or None, "
                          f"got {column_smoothing!r}") from None
    if not 0 <= p1 <= p2:
        raise StereoError(f"column_smoothing needs 0 <= p1 <= p2, got {column_smoothing!r}")
    return p1, p2


def _as_dict(options) -> dict[str, Any]:
    def plain(v):
        return list(v) if isinstance(v, tuple) else v
    return {f.name: plain(getattr(options, f.name)) for f in dataclasses.fields(options)}


def _non_defaults(options) -> dict[str, Any]:
    default = type(options)()
    return {f.name: getattr(options, f.name) for f in dataclasses.fields(options)
            if getattr(options, f.name) != getattr(default, f.name)}
