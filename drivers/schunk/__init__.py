"""SCHUNK EGU / EGK / EZU mechatronic grippers: the web API (HTTP) and Modbus RTU, sans-IO at the core.

``protocol`` (process data, parameters, byte orders, the command-received toggle), ``webapi`` (the HTTP
parameter link), ``client`` (a unit over either link, commands as SCHUNK's driver sends them) and ``sim``
(the device model and its servers). Facts and sources: docs/protocols-schunk.md.
"""
