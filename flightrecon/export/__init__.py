"""flightrecon.export"""
