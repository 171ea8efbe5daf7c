# %% [markdown]
# # A tour of the Python API
#
# One emergency stop of the paper's scenario 6 (E402B + 32 Shimmns of 50 t from 100 km/h), its
# time series as a DataFrame and a coupler-force map, then a small campaign of randomised trains
# and the tail of their buff forces. A Jupyter notebook in the percent format: open it with
# jupytext (`jupytext --to notebook examples/analysis_tour.py`), or run it as a script
# (`./dev.sh run python examples/analysis_tour.py`); the test suite runs it, so it stays
# current. In Jupyter the plots show inline; figures are also written to the folder in
# `LTD_TOUR_OUT` (default: the working directory).

# %%
import os
from pathlib import Path

import matplotlib.pyplot as plt

from ltd_brake_ros import emergency_stop, load_campaign, load_consist, read_campaign, run_campaign

out = Path(os.environ.get("LTD_TOUR_OUT", "."))
out.mkdir(parents=True, exist_ok=True)

# %% [markdown]
# ## One stop: summary, verdicts, time series

# %%
run = emergency_stop(load_consist("scenario_6"), 100.0, sample_s=0.05)
s = run.summary
print(f"stopping distance {s.stopping_distance_m:.1f} m in {s.stop_time_s:.2f} s")
print(f"peak draft {s.peak_draft_kN:.0f} kN at coupler {s.peak_draft_coupler}, "
      f"peak buff {s.peak_buff_kN:.0f} kN at coupler {s.peak_buff_coupler}")
print("verdicts:", run.verdicts.status)
run  # a notebook shows the run as one line, or as a small table

# %%
vehicles = run.to_dataframe("vehicle")  # time_s, vehicle, position_m, speed_m_s, ...
couplers = run.to_dataframe("coupler")  # time_s, coupler, coupler_force_N (draft positive)
print(vehicles.head())
print(couplers.attrs["units"])

# %% [markdown]
# ## Coupler-force map: where and when the train pulls and pushes

# %%
ds = run.to_xarray()
force_kN = ds.coupler_force_N / 1e3
fig, ax = plt.subplots(figsize=(8, 4))
mesh = ax.pcolormesh(ds.coupler, ds.time, force_kN, cmap="RdBu_r", shading="nearest",
                     vmin=-abs(force_kN).max(), vmax=abs(force_kN).max())
fig.colorbar(mesh, label="coupler force [kN], draft positive")
ax.set_xlabel("coupler (1 behind the head)")
ax.set_ylabel("time after the emergency command [s]")
fig.tight_layout()
fig.savefig(out / "coupler_force_map.png", dpi=90)
plt.show()

# %% [markdown]
# ## A small campaign: randomised coil trains, the tail of the buff force
#
# Built from a mapping (a campaign file holds the same); a few dozen stops take seconds.

# %%
campaign = load_campaign({
    "name": "tour", "seed": 7, "runs": 24, "batch_size": 8,
    "manoeuvres": [{"kind": "emergency", "speed_kmh": {"uniform": [60.0, 100.0]}}],
    "families": [{"name": "coil_trains", "wagons": [8, 16], "g_fraction": 0.1,
                  "wagon_types": {"Shimmns": {"tare_t": 22.0, "loaded_fraction": 0.7,
                                              "payload_t": {"uniform": [20.0, 58.0]}}}}],
    "couplers": [{"file": "couplers/buffer_hook_pugi.yaml"}],
})
res = run_campaign(campaign, out / "tour_campaign", jobs=1)  # a progress bar in Jupyter
runs = res.to_dataframe()
buff = runs.peak_buff_kN.abs()
print(f"{len(runs)} runs; |peak buff| quantiles [kN]:")
print(buff.quantile([0.5, 0.9, 0.99]).round(1).to_string())
worst = buff.idxmax()
print("worst run:", {c: runs.at[worst, c] for c in ("run_id", "wagons", "speed_kmh",
                                                   "peak_buff_kN")})

# %% [markdown]
# The report's quantiles with their intervals (none where fewer than 20 runs lie beyond q),
# and the exceedance curve of the buff force, worst to the right.

# %%
print(res.quantiles([0.5, 0.9], kpi="peak_buff_kN")[["q", "estimate", "low", "high", "note"]])
curve = res.exceedance_curve("peak_buff_kN")
fig, ax = plt.subplots(figsize=(6, 3.5))
ax.step(curve.value, curve.share, where="pre")
ax.set_yscale("log")
ax.invert_xaxis()
ax.set_xlabel("peak buff force [kN] (more negative is worse)")
ax.set_ylabel("share of runs at or beyond")
fig.tight_layout()
fig.savefig(out / "buff_exceedance.png", dpi=90)
plt.show()
res
