// Filled in by the implementer of scene.
