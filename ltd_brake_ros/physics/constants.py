"""Physical constants and the thresholds every layer shares (SI unless the name says otherwise)."""

#: Gravity used by UIC 544-1 and Karwatzki's law [m/s^2].
G = 9.81
#: m/s to km/h.
KMH_PER_MS = 3.6
#: A vehicle slower than this counts as standing: the train has stopped when every vehicle is
#: [m/s]. The stopping distance runs from the brake command to that instant.
STANDSTILL_M_S = 1e-3
