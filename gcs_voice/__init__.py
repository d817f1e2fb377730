"""gcs-voice: fly a drone by voice, offline, in English or Spanish.

Pipeline: audio -> ``gcs_voice.asr`` (recogniser) -> ``gcs_voice.understanding`` (dictionary match or
rejection) -> ``gcs_voice.actions.mapper`` (setpoints) -> ``gcs_voice.link`` (MAVLink to the vehicle).
"""

__version__ = "0.1.0"
