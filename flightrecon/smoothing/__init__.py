"""flightrecon.smoothing"""
