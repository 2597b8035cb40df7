"""Blender side of the Blender backend: code that runs inside the ``bpy`` worker process only.

Nothing here is imported by the host; every module imports ``bpy``. The input is the plain scene description
made by :func:`platesynth.render.blender.describe.describe_scene` (JSON numbers in plate millimetres), so this
side knows nothing of pydantic models or files other than the ones it is told to write.
"""
