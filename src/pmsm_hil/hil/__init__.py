"""pmsm_hil.hil"""
