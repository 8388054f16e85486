"""pmsm_hil.sim_target"""
