"""The panel in the browser (``grippers panel``, ``grippers serve --http``; docs/panel.md).

One page for every family and transport, ``zenoh://`` included: it drives grippers through the
vendor-neutral :class:`~grippers.Gripper` only. Modules: ``server`` (uvicorn in a thread), ``app`` (the
routes and the WebSocket), ``session`` (one gripper: snapshot, commands, the deadman), ``control`` (which page
controls), ``recording`` (the Record toggle), ``security`` (token, Origin, Host). Needs the ``panel`` extra
(Starlette, uvicorn, websockets): import ``grippers.panel.server`` only when a panel is wanted.
"""
