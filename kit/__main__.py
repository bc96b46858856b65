"""``python -m kit``: the instructor's commands.

  run        the whole pipeline with the reference solutions on a data folder (the main job)
  data       regenerate the default data/ from the seeded scene generator
  check-data  write the data the public self-checks precompute (starter/checks/*.json: Q4 goals, Q3.3 case)
  notebooks  build the student notebooks, the answer key and the nbgrader source from solutions/
  release    write the student release (no solutions, no answer key, no autograder)

What a student runs to hand in (the PDF, the code zip) is ``python -m handin``.
"""

from __future__ import annotations

import sys

from core.commands import Command, run

COMMANDS = {
    "run": Command("kit.cli", "run_pipeline", "run the reference pipeline on a data folder and write its figures",
                   arguments="pipeline_arguments", needs=("scipy", "matplotlib"),
                   install="pip install -r requirements.txt"),
    "data": Command("kit.cli", "write_data", "regenerate the default data folder from the scene generator",
                    arguments="data_arguments", needs=("PIL",), install="pip install pillow"),
    "check-data": Command("kit.check_data", "main",
                          "write the public self-checks' precomputed data (Q4.1 goals, Q3.3 twisted-pair case)",
                          needs=("scipy",), install="pip install -r requirements.txt"),
    "notebooks": Command("kit.notebooks", "main",
                         "build the student notebooks, the answer key and the nbgrader source from solutions/",
                         needs=("nbformat",), install="pip install nbformat"),
    "release": Command("kit.release", "main", "write the student release (no solutions, key, autograder or tests)",
                       needs=("nbformat",), install="pip install nbformat"),
}


def main(argv=None) -> int:
    return run("python -m kit", __doc__, COMMANDS, argv)


if __name__ == "__main__":
    sys.exit(main())
