"""Check the built distributions in dist/: the sdist carries the release files, the wheel only the package.

Run by .ci/run after ``python -m build``; exits non-zero naming what is wrong.
"""

import sys
import tarfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DIST = ROOT / "dist"
RELEASE_FILES = ("LICENSE", "CITATION.cff", "CHANGELOG.md", "README.md", "pyproject.toml")
PACKAGE = "tromplab"


def main() -> int:
    problems = []
    sdists, wheels = sorted(DIST.glob("*.tar.gz")), sorted(DIST.glob("*.whl"))
    if len(sdists) != 1 or len(wheels) != 1:
        print(f"expected one sdist and one wheel in {DIST}, found {[p.name for p in (*sdists, *wheels)]}")
        return 1
    with tarfile.open(sdists[0]) as sdist:
        names = {name.split("/", 1)[1] for name in sdist.getnames() if "/" in name}
    problems += [f"sdist lacks {name}" for name in RELEASE_FILES if name not in names]
    with zipfile.ZipFile(wheels[0]) as wheel:
        top = {name.split("/", 1)[0] for name in wheel.namelist()}
    packages = {name for name in top if not name.endswith((".dist-info", ".data"))}
    extra = packages - {PACKAGE}
    if PACKAGE not in packages:
        problems.append(f"wheel lacks the {PACKAGE} package")
    if extra:
        problems.append(f"wheel installs more than the {PACKAGE} package: {sorted(extra)}")
    for problem in problems:
        print(problem)
    if not problems:
        print(f"{sdists[0].name}: release files present; {wheels[0].name}: top-level {sorted(top)}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
