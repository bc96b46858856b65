#!/usr/bin/env bash
# Gradescope runs this once, as root, when it builds the grading image from the autograder zip
# (unpacked in /autograder/source).  Built by `python -m autograder gradescope` from
# autograder/channels/gradescope/assets/setup.sh; @...@ fields were filled in at build time.
#
# 1. Python and the kit's requirements, in a virtual environment (@VENV@) so that the image's
#    own Python packages (and its "externally managed" pip) are left alone.
# 2. The grader's files (solutions, the grading secret, the autograder) readable by root only.
#
# No student user is created: the sandbox runs student code under a numeric uid of its own
# (60000 and up, no passwd entry needed), so it can read nothing that is not world-readable.
#
# Environment (for tests; Gradescope sets none of these):
#   HW4_AUTOGRADER_ROOT    the folder laid out like /autograder (default /autograder)
#   HW4_SETUP_SKIP_INSTALL 1: skip step 1 (no apt-get, no pip)

set -euo pipefail
ROOT="${HW4_AUTOGRADER_ROOT:-/autograder}"
SOURCE="$ROOT/source"
VENV="@VENV@"

if [ "${HW4_SETUP_SKIP_INSTALL:-0}" != 1 ]; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update
    # util-linux: unshare and setpriv, which the sandbox's strongest isolation uses.
    apt-get install -y --no-install-recommends python3 python3-venv python3-pip util-linux coreutils
    python3 -m venv "$VENV"
    "$VENV/bin/python" -m pip install --no-cache-dir --upgrade pip
    "$VENV/bin/python" -m pip install --no-cache-dir -r "$SOURCE/requirements.txt"
    # The hidden checks are pytest tests (autograder/hidden): the grader runs them with pytest.
    "$VENV/bin/python" -m pip install --no-cache-dir "pytest>=8"
    # Fail the image build now, not every submission later, when the kit cannot load.
    (cd "$SOURCE" && PYTHONPATH="$SOURCE" "$VENV/bin/python" -c "import autograder.channels.gradescope.bundle, autograder.hidden.plugin, pytest, starter, scenes, solutions")
    chmod -R a+rX "$VENV"
fi

# The sandboxed code gets copies of starter/ and scenes/ made by the grader; nothing under
# source/ has to be readable by anyone else.
chmod -R go-rwx "$SOURCE"
echo "setup.sh: done"
