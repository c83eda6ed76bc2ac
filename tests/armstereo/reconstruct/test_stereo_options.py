"""The matchers' options: validated once when made, the paper's method, the old keywords."""

import dataclasses
import json

import numpy as np
import pytest

from armstereo.errors import StereoError
from armstereo.reconstruct.stereo import (
    PAPER_OPTIONS,
    BirchfieldOptions,
    SgbmOptions,
    birchfield,
    compute_disparity,
    disparity,
    sgbm,
)
from armstereo.reconstruct.stereo_options import options_for, with_keywords
from tests.support.images import texture


def shifted_pair(d0, *, shape, seed):
    """One fronto-parallel plane at disparity ``d0``: ``left[:, x] = right[:, x - d0]``."""
    H, W = shape
    tex = texture((H, W + d0), seed)
    return tex[:, :W], np.ascontiguousarray(tex[:, d0:])


@pytest.mark.parametrize("kwargs, message", [
    (dict(color="rgb"), "color='rgb' is not one of"),
    (dict(postprocess="smooth"), "postprocess='smooth' is not one of"),
    (dict(threads=0), "threads must be >= 1"),
    (dict(match_reward=np.nan), "must be >= 0"),
    (dict(cost_window=(2, 3)), "cost_window sides must be odd"),
    (dict(cost_window=3), r"cost_window must be \(width, height\)"),
    (dict(slant_penalty=-1), "slant_penalty must be >= 0 or None"),
    (dict(consensus_size=4), "consensus_size must be 0"),
    (dict(column_smoothing=(4, 1)), "0 <= p1 <= p2"),
    (dict(column_smoothing=(1, 4), search="pruned"), 'column_smoothing needs color="gray"'),
    (dict(prefilter="highpass", prefilter_sigma=0), "prefilter_sigma"),
    (dict(prefilter="highpass", color="max"), "grey matching only"),
    (dict(normalize_window=4), "normalize_window must be 0"),
    (dict(normalize_window=True), "normalize_window must be 0"),
    (dict(normalize_window=7, normalize_floor=0), "normalize_floor"),
    (dict(plain_fill=1.5), "plain_fill must be a share"),
])
def test_a_bad_option_is_refused_when_the_options_are_made(kwargs, message):
    with pytest.raises(StereoError, match=message):
        BirchfieldOptions(**kwargs)


def test_options_are_frozen_keyword_only_and_normalised():
    o = BirchfieldOptions(postprocess=False, cost_window=[1.0, 5], column_smoothing=[1, 4])
    assert (o.postprocess, o.cost_window, o.column_smoothing) == ("none", (1, 5), (1.0, 4.0))
    assert BirchfieldOptions(postprocess=True) == BirchfieldOptions()
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.lr_check = True
    with pytest.raises(TypeError):
        BirchfieldOptions("gray")
    hash(o)  # usable as a key: no list left inside


def test_the_papers_method_is_the_published_options():
    paper = BirchfieldOptions.paper()
    assert paper == BirchfieldOptions(**PAPER_OPTIONS)
    assert paper.non_defaults() == {k: v for k, v in PAPER_OPTIONS.items()
                                    if getattr(BirchfieldOptions(), k) != v}
    assert BirchfieldOptions.paper(lr_check=True).lr_check
    assert paper.single_pixel is False and BirchfieldOptions(color="sum").single_pixel
    # the paper compares the intensities as they are, with nothing filled in
    assert (paper.equalize, paper.normalization, paper.plain_fill) == (False, None, None)
    assert BirchfieldOptions(normalize_window=7).normalization == (7, 4.0, 24.0)


def test_the_record_holds_every_option_and_reads_back():
    o = BirchfieldOptions(photo_check=4.0, column_smoothing=(1, 4))
    record = json.loads(json.dumps(o.as_dict()))
    assert set(record) == {f.name for f in dataclasses.fields(BirchfieldOptions)}
    assert BirchfieldOptions(**record) == o
    assert SgbmOptions(**SgbmOptions(block_size=7).as_dict()) == SgbmOptions(block_size=7)
    assert BirchfieldOptions().non_defaults() == {} and SgbmOptions().non_defaults() == {}


@pytest.mark.parametrize("kwargs, message", [
    (dict(block_size=4), "SGBM block_size must be odd and >= 1"),
    (dict(block_size=5.0), "block_size must be a whole number"),
    (dict(uniqueness=-1), "uniqueness must be >= 0"),
])
def test_bad_sgbm_options_are_refused(kwargs, message):
    with pytest.raises(StereoError, match=message):
        SgbmOptions(**kwargs)


def test_the_old_keywords_and_the_options_object_give_the_same_map():
    left, right = shifted_pair(6, shape=(40, 90), seed=3)
    for keywords in ({}, PAPER_OPTIONS, dict(lr_check=True, cost_window=(1, 1))):
        by_keywords = birchfield(left, right, 12, min_disparity=1, **keywords)
        by_object = birchfield(left, right, 12, BirchfieldOptions(**keywords), min_disparity=1)
        np.testing.assert_array_equal(by_keywords, by_object)
    # keywords change the given object's fields
    np.testing.assert_array_equal(birchfield(left, right, 12, BirchfieldOptions.paper(),
                                             lr_check=True),
                                  birchfield(left, right, 12, lr_check=True, **PAPER_OPTIONS))
    np.testing.assert_array_equal(sgbm(left, right, 15, SgbmOptions(block_size=7)),
                                  sgbm(left, right, 15, block_size=7))


def test_the_method_comes_from_the_options_type():
    left, right = shifted_pair(6, shape=(40, 90), seed=4)
    np.testing.assert_array_equal(disparity(left, right, 15, SgbmOptions()),
                                  sgbm(left, right, 15))
    np.testing.assert_array_equal(disparity(left, right, 15), birchfield(left, right, 15))
    np.testing.assert_array_equal(
        compute_disparity(left, right, 15, options=BirchfieldOptions(subpixel="none")),
        compute_disparity(left, right, 15, method="birchfield", subpixel="none"))
    with pytest.raises(StereoError, match="does not take SgbmOptions"):
        compute_disparity(left, right, 15, method="birchfield", options=SgbmOptions())


def test_an_unknown_keyword_is_a_type_error_naming_the_matcher():
    with pytest.raises(TypeError, match=r"birchfield\(\) got an unexpected keyword .*'block'"):
        birchfield(np.zeros((8, 20), np.uint8), np.zeros((8, 20), np.uint8), 4, block=3)
    with pytest.raises(TypeError, match=r"sgbm\(\) got an unexpected keyword .*'threads'"):
        options_for("sgbm", {"threads": 1})
    assert with_keywords(SgbmOptions(), {}, "sgbm") == SgbmOptions()


def test_old_option_dicts_become_the_methods_options():
    assert options_for(None, None) == BirchfieldOptions()
    assert options_for("birchfield", {"photo_check": 4.0}) == BirchfieldOptions(photo_check=4.0)
    assert options_for("sgbm", {"block_size": 7}) == SgbmOptions(block_size=7)
    with pytest.raises(StereoError, match="unknown stereo method 'bm'"):
        options_for("bm")


def test_the_options_types_are_importable_from_the_package():
    import armstereo

    assert armstereo.BirchfieldOptions is BirchfieldOptions
    assert armstereo.SgbmOptions is SgbmOptions
