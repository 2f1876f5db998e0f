"""Khronos glTF-Validator (npm `gltf-validator`, run with node) on a written file.

`make gltf-validator` installs the package under `<checkout>/.cache/gltf-validator`; the
environment variable NGC_GLTF_VALIDATOR may name another folder holding its node_modules."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

_SCRIPT = """
const v = require('gltf-validator');
const fs = require('fs');
const data = new Uint8Array(fs.readFileSync(process.argv[1]));
v.validateBytes(data, {maxIssues: 50}).then(r => {
  process.stdout.write(JSON.stringify({errors: r.issues.numErrors,
    warnings: r.issues.numWarnings,
    messages: r.issues.messages.filter(m => m.severity === 0).slice(0, 10)}));
}).catch(e => { process.stdout.write(JSON.stringify({errors: -1, failure: String(e)})); });
"""


def validator_dir() -> Path:
    """The folder whose node_modules holds gltf-validator."""
    env = os.environ.get("NGC_GLTF_VALIDATOR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / ".cache" / "gltf-validator"


def validator_available() -> bool:
    return shutil.which("node") is not None and \
        (validator_dir() / "node_modules" / "gltf-validator").is_dir()


def validate(path: str | os.PathLike) -> dict:
    """{errors, warnings, messages (the first errors)} of the file; RuntimeError when the
    validator is not installed (`make gltf-validator`)."""
    if not validator_available():
        raise RuntimeError("gltf-validator is not installed: run `make gltf-validator` "
                           f"(npm install under {validator_dir()})")
    env = {**os.environ, "NODE_PATH": str(validator_dir() / "node_modules")}
    run = subprocess.run(["node", "-e", _SCRIPT, os.fspath(path)], capture_output=True,
                         text=True, env=env, timeout=120)
    if run.returncode != 0 or not run.stdout:
        raise RuntimeError(f"gltf-validator failed: {(run.stderr or run.stdout)[-300:]}")
    return json.loads(run.stdout)
