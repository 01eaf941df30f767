"""flightrecon.geo"""
