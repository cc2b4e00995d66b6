// Filled in by the implementer of rolling_shutter_renderer.
