"""The web gateway: the phone page and its WebSocket bridge to the bus (upload/command
parsing, bus message -> page JSON, one page's session)."""
