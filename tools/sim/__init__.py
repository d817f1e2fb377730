"""The bundled simulator (gcs-sim): its control tuning, its MAVLink against a reference and fuzzing of its
endpoints (``python -m tools`` lists the commands)."""
