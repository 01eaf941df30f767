"""flightrecon.cli"""
