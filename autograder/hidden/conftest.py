"""The hidden checks' fixtures (``student``, ``hidden``, ``score``...) and the ``points`` marker."""

pytest_plugins = ["autograder.hidden.plugin"]
