"""The panel in the browser (``grippers panel``, ``grippers serve --http``; docs/panel.md).

One page for every family and transport, ``zenoh://`` included: it drives grippers through the
vendor-neutral :class:`~grippers.Gripper` only. Modules: ``server`` (uvicorn in a thread), ``app`` (the
routes and the WebSocket), ``pump`` (what goes to each page), ``session`` (one gripper: snapshot, commands,
the deadman), ``control`` (which page controls), ``recording`` (the Record toggle), ``security`` (token,
Origin, Host), ``launch`` (the command line's options). Needs the ``panel`` extra (Starlette, uvicorn,
websockets): ``launch`` imports none of it; ``server`` is imported only when a panel starts.
"""
