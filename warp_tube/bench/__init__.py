"""Benchmarks users can run: analytic references (:mod:`.references`)."""
