"""warp_tube tests."""
