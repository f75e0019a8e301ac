"""The error every scene check raises: a list of {path, message}, each at its JSON path."""


class SceneError(Exception):
    """An invalid scene; `errors` is a list of {"path": "objects[3].radius", "message": ...}."""

    def __init__(self, errors: list[dict[str, str]]):
        self.errors = list(errors)
        super().__init__("\n".join(f"{e['path']}: {e['message']}" if e["path"] else e["message"] for e in errors))
