"""What the autograder grades on and how long it waits: the hidden-input settings, set by the instructor.

The hidden inputs (scene variants, their seeds, noise, image sizes) are made in the grader from
a *secret*: every seed is derived from it, so two courses with two secrets test on different
scenes, and a student who knows the kit (it is public) still cannot regenerate the scenes.  The
secret and the other settings come, strongest first, from

1. an explicit ``load_config(path)`` / ``--config FILE``;
2. the file named by the environment variable ``HW4_GRADER_CONFIG`` (JSON, keys below);
3. the built-in development defaults, whose secret is public (``is_dev`` says so, the CLI warns).

``HW4_GRADER_SECRET`` overrides the secret of whichever file is used.  Keep the config file out of
the student release; the grader hides it from the sandbox anyway.

Config file (JSON, every key optional)::

    {"secret": "a long random string", "official_data": "/path/to/course-data",
     "time_scale": 1.0, "match_points": 40, "ba_points": 20, "car_times": 3}
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from core.paths import course_data_dir
from core.validate import as_positive_scalar

__all__ = [
    "DEV_SECRET", "ENV_CONFIG", "ENV_SECRET", "GRADER_VERSION", "GradingConfig", "TempleSpec",
    "load_config", "quick_config",
]

ENV_CONFIG = "HW4_GRADER_CONFIG"
ENV_SECRET = "HW4_GRADER_SECRET"
DEV_SECRET = "hw4-development-secret-public-do-not-use-for-grading"
# Bumped whenever a check changes, so that resumed batches regrade what was graded before.
GRADER_VERSION = "1"



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
        Folder of the official course data (temple/..., q6/...); used when it exists.
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

    @property
    def is_dev(self) -> bool:
        """True when the public development secret is in use: fine for testing, not for grading."""
        return self.secret == DEV_SECRET

    def seed(self, label: str) -> int:
        """The seed of the hidden input ``label`` (a 63-bit integer derived from the secret)."""
        digest = hashlib.sha256(f"{self.secret}\x00{label}".encode()).digest()
        return int.from_bytes(digest[:8], "big") >> 1

    def official_dir(self) -> Path | None:
        """The official data folder when it holds the temple files, else None."""
        path = self.official_data if self.official_data is not None else course_data_dir()
        return path if path is not None and (Path(path) / "temple" / "some_corresp.npz").is_file() else None

    def to_dict(self) -> dict:
        """The settings as a config file's JSON object (``load_config`` reads it back; secret included)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "source"}
        out["temples"] = [dataclasses.asdict(t) for t in self.temples]
        out["official_data"] = str(self.official_data) if self.official_data is not None else None
        return out

    def fingerprint(self) -> str:
        """A digest of everything that changes grades (secret included, never shown in clear)."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "source"}
        fields["official_present"] = self.official_dir() is not None
        fields["version"] = GRADER_VERSION
        text = json.dumps(fields, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


_FILE_KEYS = {"secret", "temples", "use_default_data", "official_data", "match_points", "ba_points",
              "car_times", "time_scale", "load_timeout", "comment"}


def load_config(path: str | os.PathLike | None = None, *, environ: dict | None = None) -> GradingConfig:
    """The grading settings: from ``path``, else ``$HW4_GRADER_CONFIG``, else the defaults.

    Raises
    ------
    ValueError
        When the file is not a JSON object of the keys above, or a value is out of range.
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
            raise ValueError(f"config: expected keys among {sorted(_FILE_KEYS)}, got also {sorted(unknown)}")
        values = {k: v for k, v in data.items() if k != "comment"}
        if "temples" in values:
            values["temples"] = tuple(_temple_spec(t) for t in values["temples"])
        if values.get("official_data") is not None:
            values["official_data"] = Path(values["official_data"])
    if env.get(ENV_SECRET):
        values["secret"] = env[ENV_SECRET]
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
