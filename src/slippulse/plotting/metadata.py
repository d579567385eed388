"""The parameters a figure was made with, as image metadata (PNG ``Description``, PDF ``Subject``,
SVG ``Description``): every output carries its parameters (docs/guide.md, Other parameters)."""
from __future__ import annotations

import json


def params_metadata(params, path: str) -> dict | None:
    """``savefig`` metadata holding ``params`` as JSON for the format of ``path`` (None for
    formats without a free-text field)."""
    if not hasattr(params, "as_dict"):          # a stand-in without the parameters
        return None
    stamp = "slippulse parameters (SI): " + json.dumps(params.as_dict())
    ext = path.rsplit(".", 1)[-1].lower()
    key = {"png": "Description", "pdf": "Subject", "svg": "Description"}.get(ext)
    return {key: stamp} if key else None
