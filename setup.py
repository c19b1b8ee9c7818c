"""The one build step pyproject.toml cannot declare: the wheel's `ema_contract/dbc/`.

The bus description (`ema.dbc`, `ema.eds`) lives at the top of the repository, in
`dbc/`; the wheel carries it as package data of `ema_contract`, in `ema_contract/dbc/`,
where `ema_contract.frames` finds it with importlib.resources. An editable install
(`pip install -e .`, setuptools' default lenient mode) runs from the checkout, where
`ema_contract.frames` reads `dbc/` itself; in the strict editable mode the files are
linked like every other output (`get_output_mapping`).
"""

from __future__ import annotations

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
DBC_FILES = ("ema.dbc", "ema.eds")


class build_py_with_dbc(build_py):
    """`build_py` that also puts the top-level dbc/ into ema_contract/dbc/."""

    def _dbc_mapping(self) -> dict[str, str]:
        target = Path(self.build_lib, "ema_contract", "dbc")
        return {str(target / name): str(HERE / "dbc" / name) for name in DBC_FILES}

    def run(self) -> None:
        super().run()
        if self.editable_mode:
            return
        for target, source in self._dbc_mapping().items():
            self.mkpath(str(Path(target).parent))
            self.copy_file(source, target)

    def get_output_mapping(self) -> dict[str, str]:
        return {**super().get_output_mapping(), **self._dbc_mapping()}

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        outputs = super().get_outputs(include_bytecode)
        return outputs + [t for t in self._dbc_mapping() if t not in outputs]


setup(cmdclass={"build_py": build_py_with_dbc})
