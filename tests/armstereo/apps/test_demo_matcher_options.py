"""Which matcher options the demo uses (DemoOptions.matcher_options)."""

import pytest

from armstereo.apps.demo import DEMO_SGBM, DemoOptions
from armstereo.errors import ConfigError
from armstereo.reconstruct.stereo import CLEAN_PHOTO_CHECK, BirchfieldOptions, SgbmOptions


def test_the_ideal_profile_turns_the_photo_check_on():
    assert DemoOptions(profile="ideal").matcher_options() == {"photo_check": CLEAN_PHOTO_CHECK}


def test_other_profiles_keep_the_matchers_defaults():
    assert DemoOptions(profile="realistic").matcher_options() == {}


def test_sgbm_blurs_and_averages_shifted_matches_on_every_profile():
    # the library's SGBM stays OpenCV's; the demo's takes the sub-pixel steps
    assert SgbmOptions().non_defaults() == {}
    for profile in ("realistic", "ideal"):
        assert DemoOptions(profile=profile, method="sgbm").matcher_options() == {
            "presmooth": 1.0, "shifts": 4}


def test_given_options_win():
    given = {"lr_check": True}
    assert DemoOptions(profile="ideal", stereo_options=given).matcher_options() == given


def test_the_matcher_is_an_options_object():
    assert DemoOptions(profile="ideal").matcher() == BirchfieldOptions(
        photo_check=CLEAN_PHOTO_CHECK)
    assert DemoOptions(profile="realistic").matcher() == BirchfieldOptions()
    assert DemoOptions(method="sgbm").matcher() == DEMO_SGBM
    given = BirchfieldOptions(lr_check=True)
    demo = DemoOptions(profile="ideal", stereo=given)
    assert demo.matcher() is given and demo.matcher_options() == {"lr_check": True}
    assert demo.method == "birchfield" and DemoOptions(stereo=SgbmOptions()).method == "sgbm"
    with pytest.raises(ConfigError, match="does not take SgbmOptions"):
        DemoOptions(method="birchfield", stereo=SgbmOptions()).matcher()
