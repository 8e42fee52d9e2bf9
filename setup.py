"""Build hook: the repository keeps the project's own assets at its top level (`meshes/`, `scenes/`);
a built wheel carries them inside the package as `rtchannel/_assets/{meshes,scenes}`, where
`rtchannel.assets` finds them with importlib.resources. Everything else is in pyproject.toml."""
import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ASSETS = ("meshes", "scenes")


class build_py_with_assets(build_py):
    def run(self):
        super().run()
        if self.editable_mode:  # an editable install reads the checkout's folders directly
            return
        root = Path(__file__).resolve().parent
        for name in ASSETS:
            dest = Path(self.build_lib) / "rtchannel" / "_assets" / name
            shutil.rmtree(dest, ignore_errors=True)
            shutil.copytree(root / name, dest, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))


setup(cmdclass={"build_py": build_py_with_assets})
