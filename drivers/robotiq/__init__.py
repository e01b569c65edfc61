"""Robotiq 2F-85 / 2F-140 / Hand-E: Modbus RTU codec, register map, URCap codec, device client, simulator.

Facts and their public sources: docs/protocols-robotiq.md.
"""
