"""snapwarn service: analysis (numerics), schemas, REST API, client SDK, CLI."""
