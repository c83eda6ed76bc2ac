"""Which matcher options the demo uses (DemoOptions.matcher_options)."""

from armstereo.apps.demo import DemoOptions
from armstereo.reconstruct.stereo import CLEAN_PHOTO_CHECK


def test_the_ideal_profile_turns_the_photo_check_on():
    assert DemoOptions(profile="ideal").matcher_options() == {"photo_check": CLEAN_PHOTO_CHECK}


def test_other_profiles_and_sgbm_keep_the_matchers_defaults():
    assert DemoOptions(profile="realistic").matcher_options() == {}
    assert DemoOptions(profile="ideal", method="sgbm").matcher_options() == {}


def test_given_options_win():
    given = {"lr_check": True}
    assert DemoOptions(profile="ideal", stereo_options=given).matcher_options() == given
