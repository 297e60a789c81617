"""A fleet of robots: many logs at once on Dask (one log per task), the fleet table (Parquet), wear."""
