"""Package discovery only (metadata lives in pyproject.toml).

palpate's top-level folders core/, sim/ and hardware/ are the subpackages palpate.core, palpate.sim and
palpate.hardware. setuptools' declarative find cannot add the ``palpate.`` prefix, so the subpackages are found
here: a new folder with an ``__init__.py`` is packaged without anyone having to list it. The data folders models/
and scenarios/ ship as palpate.models and palpate.scenarios, every file in them included (read with
importlib.resources, see core/world/resources.py).
"""

from setuptools import find_packages, setup

TOP = ("core", "sim", "hardware")
DATA = ("models", "scenarios")
API = "core/palpate"

packages = ["palpate"] + [f"palpate.{top}" for top in TOP + DATA]
packages += [f"palpate.{top}.{sub}" for top in TOP for sub in find_packages(top, exclude=("palpate", "palpate.*"))]

setup(
    packages=packages,
    package_dir={"palpate": API} | {f"palpate.{top}": top for top in TOP + DATA},
    package_data={f"palpate.{data}": ["**/*"] for data in DATA},
    exclude_package_data={f"palpate.{data}": ["**/__pycache__/*", "**/*.pyc"] for data in DATA},
)
