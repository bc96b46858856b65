"""The kit's bottom layer: facts and primitives that every other package may use.

Nothing here imports any other package of the kit (a test enforces it), so it can ship to
students, to the grader and to the sandbox alike:

- ``manifest``: the homework's questions, points, notebooks and functions;
- ``paths``: where the kit, its data and the official course data are;
- ``validate``: the one input checker (messages name the argument, the expectation and what came);
- ``geometry``: projection, skew, epipolar distances, F and E from cameras, a camera pair with
  its ground truth;
- ``rotations`` and ``pose``: the handout's helpers ``rodrigues``/``invRodrigues`` (scipy,
  imported on first call) and ``camera2``, here because ``judging`` needs them; students get
  them from ``starter``;
- ``refine_switch``: refineF switched off (its minimisation skipped), for the self-check and the sandbox;
- ``skeleton``: the car's keypoints and edges;
- ``text``: how numbers are printed in reports and feedback, and atomic file writes.
"""
