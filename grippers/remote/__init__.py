"""Grippers on the network over Eclipse Zenoh: ``grippers serve`` and ``zenoh://`` URLs (docs/remote.md).

Nothing outside this package imports ``zenoh`` (an extra: ``pip install 'grippers[remote]'``), and this
package imports it only when a server or a client is opened, so ``grippers --help`` never loads it.

- :mod:`.protocol` the versioned key space and JSON payloads (pure); :mod:`.payloads` API objects <-> JSON
- :mod:`.lease` the control lease (pure); :mod:`.session` Zenoh configuration
- :mod:`.server` serving grippers; :mod:`.client` the zenoh backend; :mod:`.stream` subscribed states
- :mod:`.discovery` what is served; :mod:`.schemas` JSON Schemas of the payloads
"""

from __future__ import annotations

from .discovery import served_names, served_urls

__all__ = ["served_names", "served_urls"]
