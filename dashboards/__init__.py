"""pmsm_hil.dashboards"""
