// Filled in by the implementer of ois_model.
