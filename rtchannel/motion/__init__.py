"""Motion sources: procedural generators and (later) motion-capture importers, all producing `Motion`."""
