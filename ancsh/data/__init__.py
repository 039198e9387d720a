"""ancsh.data"""
