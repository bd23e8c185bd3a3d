"""NAV_SOLUTION mode bits: the variant bits are named, and a mode reads in words with fine alignment as its phase."""

from protocols.host import NavMode, describe_nav_mode


def test_variant_bits_are_named():
    assert "256" not in repr(NavMode(263)) and "VARIANT_BIT0" in repr(NavMode(263))


def test_modes_in_words_fine_alignment_is_its_own_phase():
    assert describe_nav_mode(0x0001) == "coarse alignment"
    assert describe_nav_mode(0x0107) == "fine alignment, GNSS-aided, variant BASE"
    assert describe_nav_mode(0x040E) == "navigating, GNSS-aided, PSNS-aided, variant FEDERATED"
