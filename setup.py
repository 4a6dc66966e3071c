"""The packages and their data, which pyproject.toml cannot say: uqdrape's own packages,
its material cards and architectures, and ``uqdrape.examples``: the checkout's
``studies/`` folder (the shipped example studies with their meshes, shear tests and
measurements) installed as package data, so that its files live once in git and
``uqdrape.copy_example`` finds them in an installed package."""

from setuptools import find_namespace_packages, setup

NOT_PACKAGES = ["*__pycache__"]
EXAMPLES = ["uqdrape.examples",
            *(f"uqdrape.examples.{name}" for name in find_namespace_packages("studies", exclude=NOT_PACKAGES))]

setup(packages=find_namespace_packages(include=["uqdrape*"], exclude=NOT_PACKAGES) + EXAMPLES,
      package_dir={"uqdrape.examples": "studies"},
      package_data={"uqdrape.material": ["cards/*.toml", "cards/*.csv", "architectures/*.toml"],
                    **{name: ["*.toml", "*.csv", "*.stl", "*.inp", "*.md"] for name in EXAMPLES}})
