"""``wearnav live``: Sensor Logger's HTTP Push (and MQTT) received, stored and tracked as it arrives.

push.py      one push body, checked (4xx reasons)        store.py   SQLite, one row per message
buffer.py    a session's samples as a Recording          app.py     the Starlette receiver
tracker.py   the live path and activity (LiveTracker)    static/    the page (its drawing: report/static)
replay.py    an export sent as the app pushes it          mqtt.py    the MQTT transport
export.py    a stored session as a dataset folder        bench.py   ``wearnav live bench``
crowd.py     every session's tracker in batched ticks     trackers.py ``wearnav live track``: tracker processes, Ray
store_pg.py  the store on PostgreSQL (spans machines)     cost.py    ``wearnav live cost``: a message's, a walker's CPU

The Sensor Logger names, units and signs are :mod:`wearnav.importers.sensorlogger_map`'s, and a
session becomes a Recording by the importer's own step (:mod:`wearnav.importers.sensorlogger_build`).
"""
