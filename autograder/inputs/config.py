"""What the autograder grades on and how long it waits: the hidden-input settings, set by the instructor.

The hidden inputs (scene variants, their seeds, noise, image sizes) are made in the grader from
a *secret*: every seed is derived from it, so two courses with two secrets test on different
scenes, and a student who knows the kit (it is public) still cannot regenerate the scenes.  The
hidden scenes are drawn per submission, from the secret and a digest of the submission's code
(``autograder.inputs.build.code_salt``): a regrade gets the same scenes, another submission
others; results name the draw only by ``GradingConfig.draw_digest``.  The
secret and the other settings come, strongest first, from

1. an explicit ``load_config(path)`` / ``--config FILE``;
2. the file named by the environment variable ``HW4_GRADER_CONFIG`` (JSON, keys below);
3. the built-in development defaults, whose secret is public (``is_dev`` says so, the CLI warns).

``HW4_GRADER_SECRET`` overrides the secret of whichever file is used.  Keep the config file out of
the student release; the grader hides it from the sandbox anyway.

The official course data is used only when asked for: ``load_config(official_data=DIR)`` (the
CLI's ``--official-data DIR``), the config file's ``official_data``, or ``HW4_COURSE_DATA`` set in
the environment (read only when the config file does not name ``official_data`` itself).  A
folder beside the kit is never picked up by itself.

``configuration(config, ...)`` is what every result records about how it was graded (grader and
kit version, a fingerprint of the secret, the data, the settings, the hidden tests' files and the
sandbox's isolation level); ``configuration_key`` is the part of it that must agree for results
to share one gradebook, and ``configuration_changes`` says in words how two records differ.

Config file (JSON, every key optional)::

    {"secret": "a long random string", "official_data": "/path/to/course-data",
     "time_scale": 1.0, "match_points": 40, "ba_points": 20, "car_times": 3,
     "library_calls": ["cv2.findFundamentalMat", "cv2.triangulatePoints"]}

``library_calls`` is not a grading setting: it names the library functions whose use the staff
are shown (summary.md, the class report, found by ``autograder.review.library_calls``;
``DEFAULT_LIBRARY_CALLS`` below when it is not given), so it is left out of ``fingerprint`` and of the
configuration record, and changing it regrades nothing.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from core.paths import ENV_COURSE_DATA, KIT_ROOT
from core.validate import as_positive_scalar

__all__ = [
    "DEFAULT_LIBRARY_CALLS", "DEV_SECRET", "ENV_CONFIG", "ENV_SECRET", "GRADER_VERSION", "GradingConfig", "TempleSpec",
    "configuration", "configuration_changes", "configuration_key", "load_config", "quick_config",
    "data_digest", "library_names", "tests_fingerprint", "tree_digest",
]

ENV_CONFIG = "HW4_GRADER_CONFIG"
ENV_SECRET = "HW4_GRADER_SECRET"
DEV_SECRET = "hw4-development-secret-public-do-not-use-for-grading"
# Bumped whenever a check changes, so that resumed batches regrade what was graded before.
GRADER_VERSION = "1"


# listed name -> what of the homework it does (shown beside each use)
DEFAULT_LIBRARY_CALLS: dict[str, str] = {
    "cv2.findFundamentalMat": "eightpoint / RANSAC",
    "cv2.findEssentialMat": "essentialMatrix",
    "cv2.triangulatePoints": "triangulate",
    "cv2.recoverPose": "findM2",
    "cv2.decomposeEssentialMat": "findM2",
    "cv2.computeCorrespondEpilines": "epipolarCorrespondence",
    "cv2.matchTemplate": "epipolarCorrespondence",
    "cv2.StereoBM": "epipolarCorrespondence",
    "cv2.StereoBM_create": "epipolarCorrespondence",
    "cv2.StereoSGBM": "epipolarCorrespondence",
    "cv2.StereoSGBM_create": "epipolarCorrespondence",
    "cv2.BFMatcher": "epipolarCorrespondence",
    "cv2.BFMatcher_create": "epipolarCorrespondence",
    "cv2.FlannBasedMatcher": "epipolarCorrespondence",
    "cv2.Rodrigues": "rodrigues / invRodrigues",
    "cv2.sfm": "two-view reconstruction",
    "scipy.spatial.transform.Rotation": "rodrigues / invRodrigues",
    "skimage.measure.ransac": "RANSAC",
    "skimage.transform.FundamentalMatrixTransform": "eightpoint",
    "skimage.transform.EssentialMatrixTransform": "essentialMatrix",
    "sklearn.linear_model.RANSACRegressor": "RANSAC",
    "kornia.geometry.epipolar": "two-view geometry",
}
_DOTTED = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)+$")


def library_names(names: Iterable[str] | None = None) -> dict[str, str]:
    """The names to look for -> what they do: ``DEFAULT_LIBRARY_CALLS`` when ``names`` is None,
    else exactly ``names`` (described from the default list where it knows them).

    Raises ValueError unless ``names`` is None or a list of dotted names (``cv2.findFundamentalMat``):
    a bare name would match a student's own variables.
    """
    if names is None:
        return dict(DEFAULT_LIBRARY_CALLS)
    if isinstance(names, (str, bytes)) or not all(isinstance(n, str) and _DOTTED.match(n) for n in names):
        raise ValueError("library_calls: expected a list of dotted names like \"cv2.findFundamentalMat\", "
                         f"got {names!r}")
    return {n: DEFAULT_LIBRARY_CALLS.get(n, "") for n in names}

@dataclass(frozen=True)
class TempleSpec:
    """One hidden temple scene: image size (pixels) and the Gaussian noise (pixels) of its points."""

    width: int
    height: int
    noise_px: float


@dataclass(frozen=True)
class GradingConfig:
    """The grader's settings (see the module docstring for where they come from).

    secret : str
        Every hidden seed is derived from it.
    temples : tuple of TempleSpec
        Hidden temple scenes besides the default data; the first two are used for matching and
        bundle adjustment too.
    use_default_data : bool
        Also test on the scene behind the kit's published data/ (students have seen it, so it is
        never the only scene of a check).
    official_data : Path or None
        Folder of the official course data (temple/..., q6/...); used when given and it holds
        the temple files.  None (the default): the official data is not used.
    match_points : int
        Points of image 1 matched per scene in Q4.
    ba_points : int
        Correspondences in each bundle-adjustment problem (the handout's ``minimize`` needs
        seconds per problem beyond about 20).
    car_times : int
        Time steps of the hidden car sequence (Q6).
    time_scale : float
        Multiplies every time limit given to student code (tests use less than 1).
    load_timeout : float
        Seconds to load a submission's code in the sandbox.
    library_calls : tuple of str or None
        Dotted names of the library functions to list for the staff (None: the kit's default
        list); changes no grade, so it is not part of the configuration (module docstring).
    source : Path or None
        The file the settings were read from (hidden from the sandbox); None for the defaults.
    """

    secret: str = DEV_SECRET
    temples: tuple[TempleSpec, ...] = (TempleSpec(320, 240, 0.5), TempleSpec(400, 300, 0.7))
    use_default_data: bool = True
    official_data: Path | None = None
    match_points: int = 40
    ba_points: int = 20
    car_times: int = 3
    time_scale: float = 1.0
    load_timeout: float = 90.0
    library_calls: tuple[str, ...] | None = None
    source: Path | None = field(default=None, compare=False)

    def __post_init__(self):
        if not isinstance(self.secret, str) or not self.secret:
            raise ValueError(f"secret: expected a non-empty str, got {self.secret!r}")
        if len(self.temples) < 2:
            raise ValueError(f"temples: expected at least 2 hidden temple scenes, got {len(self.temples)}")
        for name, lo in (("match_points", 8), ("ba_points", 8), ("car_times", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < lo:
                raise ValueError(f"{name}: expected an integer >= {lo}, got {value!r}")
        as_positive_scalar(self.time_scale, "time_scale")
        as_positive_scalar(self.load_timeout, "load_timeout")
        if self.library_calls is not None:
            library_names(self.library_calls)  # raises ValueError naming the key

    def library_names(self) -> dict[str, str]:
        """The library names to list for the staff -> what of the homework each one does."""
        return library_names(self.library_calls)

    @property
    def is_dev(self) -> bool:
        """True when the public development secret is in use: fine for testing, not for grading."""
        return self.secret == DEV_SECRET

    def seed(self, label: str) -> int:
        """The seed of the hidden input ``label`` (a 63-bit integer derived from the secret)."""
        digest = hashlib.sha256(f"{self.secret}\x00{label}".encode()).digest()
        return int.from_bytes(digest[:8], "big") >> 1

    def draw_digest(self, salt: str) -> str:
        """A short digest naming the hidden draw of ``salt`` (a submission's code digest) under this
        secret: equal digests, equal scenes.  Results carry it instead of anything of the scenes;
        it reveals no seed (the secret is part of it, and one digest cannot be turned back)."""
        if not isinstance(salt, str) or not salt:
            raise ValueError(f"salt: expected a non-empty str, got {salt!r}")
        return hashlib.sha256(f"hw4-draw\x00{self.secret}\x00{salt}".encode()).hexdigest()[:12]

    def official_dir(self) -> Path | None:
        """The official data folder when one was asked for and it holds the temple files, else None."""
        path = self.official_data
        return Path(path) if path is not None and (Path(path) / "temple" / "some_corresp.npz").is_file() else None

    def to_dict(self) -> dict:
        """The settings as a config file's JSON object (``load_config`` reads it back; secret included)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "source"}
        out["temples"] = [dataclasses.asdict(t) for t in self.temples]
        out["official_data"] = str(self.official_data) if self.official_data is not None else None
        out["library_calls"] = list(self.library_calls) if self.library_calls is not None else None
        return out

    def fingerprint(self) -> str:
        """A digest of everything that changes grades (secret included, never shown in clear)."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name not in _NOT_GRADING}
        fields["official_present"] = self.official_dir() is not None
        fields["version"] = GRADER_VERSION
        text = json.dumps(fields, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


_FILE_KEYS = {"secret", "temples", "use_default_data", "official_data", "match_points", "ba_points",
              "car_times", "time_scale", "load_timeout", "library_calls", "comment"}
# fields that change no grade: not in the fingerprint nor in the configuration record
_NOT_GRADING = ("source", "library_calls")


def load_config(path: str | os.PathLike | None = None, *, environ: dict | None = None,
                official_data: str | os.PathLike | None = None) -> GradingConfig:
    """The grading settings: from ``path``, else ``$HW4_GRADER_CONFIG``, else the defaults.

    ``official_data``: the official course data folder to grade with too (overrides the file's
    and ``$HW4_COURSE_DATA``); it must hold ``temple/some_corresp.npz``.

    Raises
    ------
    ValueError
        When the file is not a JSON object of the keys above, or a value is out of range, or the
        official data asked for is not a course data folder.
    FileNotFoundError
        When a named config file does not exist.
    """
    env = os.environ if environ is None else environ
    if path is None and env.get(ENV_CONFIG):
        path = env[ENV_CONFIG]
    values: dict = {}
    source = None
    if path is not None:
        source = Path(path).resolve()
        try:
            data = json.loads(source.read_text(encoding="utf-8"))
        except ValueError as exc:
            raise ValueError(f"config: expected a JSON object in {source} ({exc})") from None
        if not isinstance(data, dict):
            raise ValueError(f"config: expected a JSON object in {source}, got {type(data).__name__}")
        unknown = set(data) - _FILE_KEYS
        if unknown:
            import difflib

            hints = [f"{k!r} (did you mean {close[0]!r}?)" if (close := difflib.get_close_matches(k, _FILE_KEYS, 1))
                     else repr(k) for k in sorted(unknown)]
            raise ValueError(f"config: unknown key {', '.join(hints)} in {source}; expected keys among "
                             f"{sorted(_FILE_KEYS)}")
        values = {k: v for k, v in data.items() if k != "comment"}
        if values.get("library_calls") is not None:
            if not isinstance(values["library_calls"], list):
                raise ValueError("library_calls: expected a list of dotted names like \"cv2.findFundamentalMat\", "
                                 f"got {values['library_calls']!r} in {source}")
            values["library_calls"] = tuple(values["library_calls"])
        if "temples" in values:
            values["temples"] = tuple(_temple_spec(t) for t in values["temples"])
        if values.get("official_data") is not None:
            values["official_data"] = Path(values["official_data"])
    if env.get(ENV_SECRET):
        values["secret"] = env[ENV_SECRET]
    if official_data is not None:
        values["official_data"] = Path(official_data)
    elif "official_data" not in values and env.get(ENV_COURSE_DATA):
        values["official_data"] = Path(env[ENV_COURSE_DATA])
    folder = values.get("official_data")
    if folder is not None:
        folder = Path(folder).expanduser().resolve()
        if not (folder / "temple" / "some_corresp.npz").is_file():
            raise ValueError(f"official_data: expected a course data folder holding temple/some_corresp.npz, "
                             f"got {folder}")
        values["official_data"] = folder
    return GradingConfig(**values, source=source)


def _temple_spec(item) -> TempleSpec:
    if not (isinstance(item, dict) and set(item) == {"width", "height", "noise_px"}):
        raise ValueError(f"temples: expected objects with width, height and noise_px, got {item!r}")
    return TempleSpec(int(item["width"]), int(item["height"]), float(item["noise_px"]))


def quick_config(**changes) -> GradingConfig:
    """Small, fast settings for the kit's own tests and benchmarks (never for real grading)."""
    base = GradingConfig(temples=(TempleSpec(256, 192, 0.5), TempleSpec(320, 240, 0.6)),
                         match_points=24, ba_points=12, car_times=2, time_scale=0.5, load_timeout=60.0)
    return dataclasses.replace(base, **changes)


# ------------------------------------------------------------------------------------------------
# what every result records about its grading


def kit_version() -> str:
    """The kit's version (its installed distribution's, else pyproject.toml's), or "unknown"."""
    try:
        from importlib.metadata import version

        return version("hw4-twoview-kit")
    except Exception:  # noqa: BLE001 - not installed: read the source tree
        pass
    try:
        import re

        text = (KIT_ROOT / "pyproject.toml").read_text(encoding="utf-8")
        found = re.search(r'^version\s*=\s*"([^"]+)"', text, re.MULTILINE)
        return found.group(1) if found else "unknown"
    except OSError:
        return "unknown"


def _files_digest(paths) -> tuple[str, dict]:
    """(digest of all, {name: digest of each}) of the files ``paths`` as (name, Path) pairs."""
    every = hashlib.sha256()
    each = {}
    for name, p in sorted(paths):
        d = hashlib.sha256(Path(p).read_bytes()).hexdigest()[:16]
        each[name] = d
        every.update(f"{name}\0{d}\n".encode())
    return every.hexdigest()[:16], each


def _tree(root: Path, pattern: str, label: str) -> list[tuple[str, Path]]:
    return [(f"{label}/{p.relative_to(root).as_posix()}", p) for p in sorted(root.glob(pattern))
            if p.is_file() and "__pycache__" not in p.parts]


def tests_fingerprint(extra_tests=()) -> dict:
    """What the checks are made of: digests of the hidden tests (``autograder/hidden``), of the
    judging code and thresholds they call (``judging``) and of an
    instructor's extra test files or folders.

    Returns ``{"digest": all of them, "hidden": ..., "judging": ..., "extra": ... or None,
    "files": {name: digest}}`` (names like ``hidden/test_pose.py``, ``extra/test_x.py``).
    """
    auto = Path(__file__).resolve().parents[1]
    # The checks, the inputs they are given (scenes, cases) and the words they say.
    hidden = (_tree(auto / "hidden", "*.py", "hidden") + _tree(auto / "hidden", "*.ini", "hidden")
              + _tree(auto / "inputs", "**/*.py", "inputs") + _tree(auto / "feedback", "words.py", "feedback"))
    judging = _tree(KIT_ROOT / "judging", "**/*.py", "judging")
    extra: list[tuple[str, Path]] = []
    for item in extra_tests or ():
        item = Path(item)
        if item.is_dir():
            extra += _tree(item, "**/*.py", f"extra/{item.name}")
        elif item.is_file():
            extra.append((f"extra/{item.name}", item))
    h, h_files = _files_digest(hidden)
    j, j_files = _files_digest(judging)
    e, e_files = _files_digest(extra) if extra else (None, {})
    every = hashlib.sha256(f"{h}|{j}|{e}".encode()).hexdigest()[:16]
    return {"digest": every, "hidden": h, "judging": j, "extra": e, "files": {**h_files, **j_files, **e_files}}


def tree_digest(root: Path, pattern: str, label: str) -> str:
    """A digest (16 hex digits) of the files under ``root`` matching ``pattern``: their names
    (relative to ``root``, after ``label``) and contents."""
    return _files_digest(_tree(root, pattern, label))[0]


def data_digest(folder: Path) -> str:
    """The digest a configuration records of a data folder (every file under it)."""
    return tree_digest(folder, "**/*", "data")


def configuration(config: GradingConfig, *, extra_tests=(), isolation: str | None = None,
                  tests: dict | None = None, draw: str | None = None) -> dict:
    """What a result records about how it was graded (plain JSON; the secret only as a fingerprint).

    Keys: ``grader_version``, ``kit_version``, ``secret_fingerprint``, ``dev_secret``, ``data``
    (``default_data``: bool, ``official_data``: path or None, ``official_digest``), ``settings``
    (every other setting), ``tests`` (``tests_fingerprint``; pass ``tests`` to reuse one),
    ``isolation`` (the sandbox level, or None before a sandbox ran), ``draw`` (only when given:
    ``GradingConfig.draw_digest`` of the submission's hidden draw, never the scenes), ``key``
    (``configuration_key`` of the rest; the draw is not part of it, as every submission has its own).
    """
    official = config.official_dir()
    settings = config.to_dict()
    for name in ("secret", "official_data", "use_default_data", *_NOT_GRADING):
        settings.pop(name, None)
    record = {
        "grader_version": GRADER_VERSION,
        "kit_version": kit_version(),
        "secret_fingerprint": hashlib.sha256(f"hw4-secret\0{config.secret}".encode()).hexdigest()[:12],
        "dev_secret": config.is_dev,
        "data": {"default_data": bool(config.use_default_data),
                 "official_data": str(official) if official is not None else None,
                 "official_digest": data_digest(official) if official is not None else None},
        "settings": settings,
        "tests": tests if tests is not None else tests_fingerprint(extra_tests),
        "isolation": isolation,
    }
    if draw is not None:
        record["draw"] = draw
    record["key"] = configuration_key(record)
    return record


def configuration_key(record: dict) -> str:
    """A digest of the parts of a configuration record that change grades (not the isolation
    level, the data folder's path or the per-file digests): equal keys may share a gradebook."""
    data = record.get("data") or {}
    tests = record.get("tests") or {}
    core_parts = {
        "grader_version": record.get("grader_version"), "kit_version": record.get("kit_version"),
        "secret": record.get("secret_fingerprint"), "settings": record.get("settings"),
        "default_data": data.get("default_data"), "official": data.get("official_digest"),
        "tests": tests.get("digest"),
    }
    return hashlib.sha256(json.dumps(core_parts, sort_keys=True, default=str).encode()).hexdigest()[:16]


def configuration_changes(old: dict | None, new: dict | None) -> list[str]:
    """Sentences saying how configuration record ``new`` differs from ``old`` (empty: the same)."""
    if not old or not new:
        return [] if old == new else ["the earlier result records no configuration"]
    out = []
    if old.get("grader_version") != new.get("grader_version"):
        out.append(f"grader version {old.get('grader_version')} -> {new.get('grader_version')}")
    if old.get("kit_version") != new.get("kit_version"):
        out.append(f"kit version {old.get('kit_version')} -> {new.get('kit_version')}")
    if old.get("secret_fingerprint") != new.get("secret_fingerprint"):
        dev = {True: " (development secret)", False: ""}
        out.append(f"secret {old.get('secret_fingerprint')}{dev[bool(old.get('dev_secret'))]} -> "
                   f"{new.get('secret_fingerprint')}{dev[bool(new.get('dev_secret'))]} (other hidden scenes)")
    od, nd = old.get("data") or {}, new.get("data") or {}
    if od.get("default_data") != nd.get("default_data"):
        out.append(f"default data {'used' if od.get('default_data') else 'not used'} -> "
                   f"{'used' if nd.get('default_data') else 'not used'}")
    if od.get("official_digest") != nd.get("official_digest"):
        out.append(f"official data {od.get('official_data') or 'not used'} -> {nd.get('official_data') or 'not used'}")
    os_, ns = old.get("settings") or {}, new.get("settings") or {}
    for name in sorted(set(os_) | set(ns)):
        if os_.get(name) != ns.get(name):
            out.append(f"setting {name} {os_.get(name)!r} -> {ns.get(name)!r}")
    ot, nt = old.get("tests") or {}, new.get("tests") or {}
    if ot.get("digest") != nt.get("digest"):
        of, nf = ot.get("files") or {}, nt.get("files") or {}
        changed = sorted(n for n in set(of) | set(nf) if of.get(n) != nf.get(n))
        if changed:
            shown = ", ".join(changed[:8]) + (f" and {len(changed) - 8} more" if len(changed) > 8 else "")
            out.append(f"test files changed: {shown}")
        else:
            out.append("the hidden tests changed")
    return out
