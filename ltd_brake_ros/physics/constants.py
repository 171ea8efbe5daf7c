"""Physical constants and the thresholds every layer shares (SI unless the name says otherwise)."""

#: Gravity used by UIC 544-1 and Karwatzki's law [m/s^2].
G = 9.81
#: m/s to km/h.
KMH_PER_MS = 3.6
#: A vehicle moving forward slower than this counts as standing [m/s]: the train has stopped
#: when no vehicle moves forward faster (one pulled back as the couplers relax after the stop,
#: a locomotive whose brake holds less than the train's stored draft, has stopped too). The
#: stopping distance runs from the brake command to that instant.
STANDSTILL_M_S = 1e-3
