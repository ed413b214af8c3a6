#!/usr/bin/env python3
"""Generate the Python bindings of the Find Me bus schemas.

    python tools/gen_schemas.py            # regenerate schemas/v1/*_pb2.py and *_pb2.pyi
    python tools/gen_schemas.py --check    # exit 1 if the committed files are out of date
    python tools/gen_schemas.py --out DIR  # write DIR/schemas/v1/*_pb2.py(i) instead

Inputs are ``schemas/v1/*.proto`` (package ``findme.v1``), compiled with the repository
root as the only include path, so the generated modules import each other as
``from schemas.v1 import common_pb2``, i.e. as part of the installed ``schemas`` package.

Foxglove well-known types (``import "foxglove/CompressedImage.proto";``) are not read from
.proto files: the pip package ``foxglove-schemas-protobuf`` ships only generated Python,
so their descriptors are taken from it and handed to protoc with ``--descriptor_set_in``.
protoc then writes ``from foxglove import CompressedImage_pb2``, a module that does not
exist (and would clash with the ``foxglove`` module of foxglove-sdk); this script rewrites
those imports to ``from foxglove_schemas_protobuf import CompressedImage_pb2``, which
registers the same file name ("foxglove/CompressedImage.proto") in the descriptor pool.

The output is byte-for-byte reproducible for a given protoc (grpcio-tools) version; the
version that produced the committed files is in their "Protobuf Python Version" header.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROTO_SUBDIR = Path("schemas") / "v1"
FOXGLOVE_PROTO_PREFIX = "foxglove/"
FOXGLOVE_MODULE = "foxglove_schemas_protobuf"

_IMPORT_RE = re.compile(r'^\s*import\s+(?:public\s+|weak\s+)?"([^"]+)"\s*;', re.MULTILINE)
_FOXGLOVE_IMPORT_RE = re.compile(r"^from foxglove import ", re.MULTILINE)
_GENERATED_RE = re.compile(r".*_pb2\.pyi?$")


def proto_files(root: Path) -> list[Path]:
    """The .proto files of the current schema version, sorted."""
    files = sorted((root / PROTO_SUBDIR).glob("*.proto"))
    if not files:
        raise SystemExit(f"no .proto files in {root / PROTO_SUBDIR}")
    return files


def _foxglove_descriptor_set(protos: list[Path]) -> bytes:
    """A serialized FileDescriptorSet with every foxglove file the protos import, plus
    their dependencies (google/protobuf/timestamp.proto, ...)."""
    from google.protobuf import descriptor_pb2

    wanted = sorted({name for p in protos for name in _IMPORT_RE.findall(p.read_text())
                     if name.startswith(FOXGLOVE_PROTO_PREFIX)})
    fds = descriptor_pb2.FileDescriptorSet()
    seen: set[str] = set()

    def add(fd) -> None:
        if fd.name in seen:
            return
        seen.add(fd.name)
        for dep in fd.dependencies:
            add(dep)
        fd.CopyToProto(fds.file.add())

    for name in wanted:
        stem = name[len(FOXGLOVE_PROTO_PREFIX):-len(".proto")]
        module = f"{FOXGLOVE_MODULE}.{stem}_pb2"
        try:
            mod = importlib.import_module(module)
        except ImportError as exc:
            raise SystemExit(f"{name} is imported by a schema but {module} cannot be "
                             f"imported ({exc}); install foxglove-schemas-protobuf") from exc
        if mod.DESCRIPTOR.name != name:
            raise SystemExit(f"{module} registers {mod.DESCRIPTOR.name!r}, expected {name!r}")
        add(mod.DESCRIPTOR)
    return fds.SerializeToString()


def _rewrite(text: str, path: Path) -> str:
    """Point protoc's foxglove imports at foxglove_schemas_protobuf."""
    text = _FOXGLOVE_IMPORT_RE.sub(f"from {FOXGLOVE_MODULE} import ", text)
    if re.search(r"^(from|import) foxglove\b(?!_schemas_protobuf)", text, re.MULTILINE):
        raise SystemExit(f"{path}: an import of 'foxglove' was left unrewritten")
    return text


def generate(out: Path, root: Path = ROOT) -> list[Path]:
    """Compile root/schemas/v1/*.proto into out/schemas/v1/*_pb2.py(i).

    Stale *_pb2.py(i) files in the output directory (whose .proto is gone) are removed.
    Returns the written files.
    """
    from grpc_tools import protoc

    protos = proto_files(root)
    with tempfile.TemporaryDirectory(prefix="gen_schemas_") as tmp_s:
        tmp = Path(tmp_s)
        deps = tmp / "foxglove.fds"
        deps.write_bytes(_foxglove_descriptor_set(protos))
        gen = tmp / "out"
        gen.mkdir()
        args = ["protoc", f"--descriptor_set_in={deps}", f"--proto_path={root}",
                f"--python_out={gen}", f"--pyi_out={gen}",
                *(str(p) for p in protos)]
        rc = protoc.main(args)
        if rc != 0:
            raise SystemExit(f"protoc failed with exit code {rc} (its message is above)")

        src_dir = gen / PROTO_SUBDIR
        dst_dir = out / PROTO_SUBDIR
        dst_dir.mkdir(parents=True, exist_ok=True)
        produced = sorted(p for p in src_dir.iterdir() if _GENERATED_RE.match(p.name))
        names = {p.name for p in produced}
        for old in dst_dir.iterdir():
            if _GENERATED_RE.match(old.name) and old.name not in names:
                old.unlink()
        written = []
        for p in produced:
            text = _rewrite(p.read_text(encoding="utf-8"), p)
            dst = dst_dir / p.name
            if not dst.exists() or dst.read_bytes() != text.encode("utf-8"):
                dst.write_bytes(text.encode("utf-8"))
            written.append(dst)
        return written


def generated_files(root: Path) -> dict[str, bytes]:
    """name -> bytes of the generated files under root/schemas/v1."""
    d = root / PROTO_SUBDIR
    if not d.is_dir():
        return {}
    return {p.name: p.read_bytes() for p in sorted(d.iterdir()) if _GENERATED_RE.match(p.name)}


def check(root: Path = ROOT) -> list[str]:
    """Problems (empty when in sync) between the committed and freshly generated files."""
    with tempfile.TemporaryDirectory(prefix="gen_schemas_check_") as tmp:
        generate(Path(tmp), root)
        fresh = generated_files(Path(tmp))
    committed = generated_files(root)
    problems = [f"{PROTO_SUBDIR / n}: missing (run tools/gen_schemas.py)"
                for n in sorted(fresh.keys() - committed.keys())]
    problems += [f"{PROTO_SUBDIR / n}: stale, its .proto is gone (run tools/gen_schemas.py)"
                 for n in sorted(committed.keys() - fresh.keys())]
    problems += [f"{PROTO_SUBDIR / n}: differs from its .proto (run tools/gen_schemas.py)"
                 for n in sorted(fresh.keys() & committed.keys()) if fresh[n] != committed[n]]
    return problems


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=None,
                    help="output root (default: the repository, i.e. overwrite schemas/v1)")
    ap.add_argument("--check", action="store_true",
                    help="do not write; exit 1 if the committed files are out of date")
    a = ap.parse_args(argv)
    if a.check:
        problems = check()
        for p in problems:
            print(p, file=sys.stderr)
        return 1 if problems else 0
    out = (a.out or ROOT).resolve()
    for p in generate(out):
        print(p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
