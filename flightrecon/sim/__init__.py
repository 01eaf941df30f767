"""flightrecon.sim"""
