"""flightrecon.ingest"""
