"""Find Me services: thin bus adapters (``runtime``) around pure handlers, one module each."""
