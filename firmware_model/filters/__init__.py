"""The navigation filter of the firmware, one module per concept (issue 42 item 6).

A variant is a :class:`~.interface.NavFilter`; the base variant, :class:`~.base.BaseFilter`, is the error-state KF of
:mod:`firmware_model.kf` with the models below. Import from the module that declares a name (this package re-exports
nothing):

==========================  ====================================================================
:mod:`.interface`           what the loop calls and offers: ``NavFilter``, ``FilterHost``, ``UpdateReport``,
                            the registry ``register_filter`` (fills :data:`firmware_model.config.FILTER_VARIANTS`)
:mod:`.base`                ``BaseFilter``: the base paper's 15-state KF (+ augmented states), predict, updates,
                            feedback; registered as ``base``
:mod:`.noise_model`         the spec sheet's Q and P0, flicker, rotation and warm-up noise, ``GyroFlickerStates``
:mod:`.gnss`                ``GnssMeasurement``, the HDOP/GST scale, the GNSS rows, ``GnssErrorStates``
:mod:`.solar`               ``SolarObservation``, the solar-vector noise and NIS, ``SolarBiasStates``
:mod:`.cycles`              C674x cycles of the predict, the scalar update and the feedback
==========================  ====================================================================
"""
