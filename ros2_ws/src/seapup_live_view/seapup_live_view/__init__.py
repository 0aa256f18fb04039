"""The live view: the ``live_view`` node serving a running graph to Foxglove (``docs/live-view.md``).

:mod:`~seapup_live_view.live_view_node` is the node (a thin shell); its pure parts are the scene
(:mod:`~seapup_live_view.view_scene`), the Foxglove messages (:mod:`~seapup_live_view.live_view_messages`),
the checks of a viewer's requests (:mod:`~seapup_live_view.view_requests`), the shipped panel layout
(:mod:`~seapup_live_view.view_layout`) and the WebSocket relay (:mod:`~seapup_live_view.view_relay`);
:mod:`~seapup_live_view.attach` puts the node beside any graph (``--view``).
"""
