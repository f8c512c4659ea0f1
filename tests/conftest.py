"""Hypothesis profiles. The default run draws the same examples every time (``derandomize``), so
a clean clone's test run is reproducible; ``--hypothesis-profile=explore`` draws new ones each
run, as the slow fuzzing tier does, to look for what the fixed examples miss."""

from hypothesis import settings

settings.register_profile("fixed", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile("fixed")  # pytest's --hypothesis-profile, read later, overrides this
