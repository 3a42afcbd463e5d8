"""What a scorecard compares in each group of its matrix: the paired metrics of the
verdict table (wtftc.campaign.scorecard.report) and of the screen's choice
(wtftc.campaign.scorecard.screen). Each is a key of a sweep's rows
(wtftc.campaign.sweep.store.METRICS)."""

#: the paired metrics of each group: (key, what, unit, lower is better)
METRICS = {
    "normal_production": [
        # where the wind is at or above rated, against rated speed (both controllers'
        # reference there; below it the speed follows the torque law's operating point,
        # which the power and the lifetime's below-rated share judge)
        ("rms_speed_error_own_above_rated_rad_s", "RMS rotor-speed error, wind above rated",
         "rad/s", True),
        ("shaft_torque_del_1hz_Nm", "shaft-torque DEL (1 Hz)", "N m", True),
        ("tower_base_del_1hz_Nm", "tower-base DEL (1 Hz)", "N m", True),
        ("blade_root_flap_del_1hz_Nm", "blade-root flapwise DEL (1 Hz, worst blade)",
         "N m", True),
        ("pitch_adc", "pitch actuator duty cycle", "-", True),
        ("pitch_rate_max_abs_deg_s", "largest pitch rate", "deg/s", True),
        ("mean_electrical_power_W", "mean electrical power", "W", False)],
    "actuator_faults": [
        ("rms_speed_error_after_fault_rad_s", "RMS rotor-speed error after the onset",
         "rad/s", True),
        ("overspeed_peak_over_rated_after_onset", "peak rotor speed / rated after the "
         "onset", "-", True),
        ("shaft_torque_del_1hz_Nm", "shaft-torque DEL (1 Hz)", "N m", True),
        ("tower_base_del_1hz_Nm", "tower-base DEL (1 Hz)", "N m", True),
        ("shaft_torque_max_abs_after_onset_Nm", "largest shaft torque after the onset",
         "N m", True),
        ("tower_base_max_abs_after_onset_Nm", "largest tower-base moment after the onset",
         "N m", True),
        ("blade_root_flap_max_abs_after_onset_Nm", "largest blade-root flapwise moment "
         "after the onset", "N m", True),
        ("pitch_adc", "pitch actuator duty cycle", "-", True),
        ("energy_after_onset_J", "energy produced after the onset", "J", False)],
    # one run a scenario, no seeds: a ratio per case, no interval
    "deterministic": [
        ("overspeed_peak_over_rated", "peak rotor speed / rated", "-", True),
        ("rms_speed_error_rad_s", "RMS rotor-speed error", "rad/s", True),
        ("shaft_torque_max_abs_Nm", "largest shaft torque", "N m", True),
        ("tower_base_max_abs_Nm", "largest tower-base moment", "N m", True),
        ("blade_root_flap_max_abs_Nm", "largest blade-root flapwise moment", "N m", True),
        ("pitch_rate_max_abs_deg_s", "largest pitch rate", "deg/s", True),
        ("pitch_adc", "pitch actuator duty cycle", "-", True)],
}
METRICS["sensor_faults"] = METRICS["actuator_faults"]
#: the baseline with the benchmark's actuator and sensors over the baseline as its deck
#: ships it: what they cost it (a ratio above 1), on the normal-production metrics
METRICS["baseline_as_shipped"] = METRICS["normal_production"]
#: the groups whose runs hold a fault from an onset
FAULT_GROUPS = ("actuator_faults", "sensor_faults")
#: the content of the loads in the rotor's 1P and 3P bands (the controller test bench's
#: spectra), in the normal-production group: (key, what, unit, lower is better)
SPECTRA = [
    ("tower_base_1p_std_Nm", "tower-base moment, 1P band", "N m", True),
    ("tower_base_3p_std_Nm", "tower-base moment, 3P band", "N m", True),
    ("blade_root_flap_1p_std_Nm", "blade-root flapwise moment, 1P band", "N m", True),
    ("blade_root_flap_3p_std_Nm", "blade-root flapwise moment, 3P band", "N m", True)]
#: the blades' pitch direction changes in the normal-production group, the mean over the
#: blades (the controller test bench's per-blade figure; its pitch travel per second is
#: the pitch actuator duty cycle times the rate limit, so the same ratio as the ADC's):
#: (key, what, unit, lower is better)
PITCH = [
    ("pitch_reversals_per_s", "pitch direction changes per second (WEIS reports it as "
     "pitch_duty_cycle)", "1/s", True)]
