"""rana: the benchmark's bundled methods — RANA (in progress), and the Lambertian-SH oracle bound."""
