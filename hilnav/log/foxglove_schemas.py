"""JSON Schemas of the Foxglove messages that the log's views use (foxglove.py).

Field names and types as Foxglove's well-known schemas; the writer stores :data:`SCHEMAS`
in the log beside each view channel, and the reader recognises a view by its schema name.
"""

from __future__ import annotations

from typing import Any

_NUM = {"type": "number"}


def _obj(title: str, props: dict[str, Any]) -> dict[str, Any]:
    return {"title": title, "type": "object", "properties": props, "required": list(props)}


_TIME = {
    "type": "object",
    "title": "time",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
    },
}
_DURATION = {
    "type": "object",
    "title": "duration",
    "properties": {
        "sec": {"type": "integer"},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
    },
}
_VEC3 = _obj("foxglove.Vector3", {"x": _NUM, "y": _NUM, "z": _NUM})
_QUAT = _obj("foxglove.Quaternion", {"x": _NUM, "y": _NUM, "z": _NUM, "w": _NUM})
_POSE = _obj("foxglove.Pose", {"position": _VEC3, "orientation": _QUAT})
_COLOR = _obj("foxglove.Color", {"r": _NUM, "g": _NUM, "b": _NUM, "a": _NUM})
_KV = _obj("foxglove.KeyValuePair", {"key": {"type": "string"}, "value": {"type": "string"}})
_STR = {"type": "string"}


def _arr(items: dict[str, Any]) -> dict[str, Any]:
    return {"type": "array", "items": items}


_POSE_IN_FRAME = _obj("foxglove.PoseInFrame", {"timestamp": _TIME, "frame_id": _STR, "pose": _POSE})
_FRAME_TRANSFORM = _obj(
    "foxglove.FrameTransform",
    {
        "timestamp": _TIME,
        "parent_frame_id": _STR,
        "child_frame_id": _STR,
        "translation": _VEC3,
        "rotation": _QUAT,
    },
)
_LOCATION_FIX = _obj(
    "foxglove.LocationFix",
    {
        "timestamp": _TIME,
        "frame_id": _STR,
        "latitude": _NUM,
        "longitude": _NUM,
        "altitude": _NUM,
        "position_covariance": {"type": "array", "items": _NUM, "minItems": 9, "maxItems": 9},
        "position_covariance_type": {
            "title": "foxglove.PositionCovarianceType",
            "oneOf": [
                {"title": "UNKNOWN", "const": 0},
                {"title": "APPROXIMATED", "const": 1},
                {"title": "DIAGONAL_KNOWN", "const": 2},
                {"title": "KNOWN", "const": 3},
            ],
        },
    },
)
_CUBE = _obj("foxglove.CubePrimitive", {"pose": _POSE, "size": _VEC3, "color": _COLOR})
_SPHERE = _obj("foxglove.SpherePrimitive", {"pose": _POSE, "size": _VEC3, "color": _COLOR})
_ARROW = _obj(
    "foxglove.ArrowPrimitive",
    {
        "pose": _POSE,
        "shaft_length": _NUM,
        "shaft_diameter": _NUM,
        "head_length": _NUM,
        "head_diameter": _NUM,
        "color": _COLOR,
    },
)
_ENTITY = {
    "title": "foxglove.SceneEntity",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "frame_id": _STR,
        "id": _STR,
        "lifetime": _DURATION,
        "frame_locked": {"type": "boolean"},
        "metadata": _arr(_KV),
        "arrows": _arr(_ARROW),
        "cubes": _arr(_CUBE),
        "spheres": _arr(_SPHERE),
        "cylinders": _arr({"type": "object"}),
        "lines": _arr({"type": "object"}),
        "triangles": _arr({"type": "object"}),
        "texts": _arr({"type": "object"}),
        "models": _arr({"type": "object"}),
    },
}
_DELETION = _obj(
    "foxglove.SceneEntityDeletion",
    {
        "timestamp": _TIME,
        "type": {
            "title": "foxglove.SceneEntityDeletionType",
            "oneOf": [{"title": "MATCHING_ID", "const": 0}, {"title": "ALL", "const": 1}],
        },
        "id": _STR,
    },
)
_SCENE_UPDATE = {
    "title": "foxglove.SceneUpdate",
    "type": "object",
    "properties": {"deletions": _arr(_DELETION), "entities": _arr(_ENTITY)},
}

SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.PoseInFrame": _POSE_IN_FRAME,
    "foxglove.FrameTransform": _FRAME_TRANSFORM,
    "foxglove.LocationFix": _LOCATION_FIX,
    "foxglove.SceneUpdate": _SCENE_UPDATE,
}
