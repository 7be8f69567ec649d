"""Device nodes: battery (/power), head, camera and hand sensors, each a small driver over a stream of /sim."""
