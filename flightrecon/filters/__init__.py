"""flightrecon.filters"""
