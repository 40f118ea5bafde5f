"""
Choosing the degree
===================

``fit_adaptive`` tries the degrees 2, 4, 6, ... and a *degree rule* decides when to stop and
which degree to keep. The default rule (``"capture"``) goes on while a degree still gains in
smoothness, F-score, recall or distance, stops once a clean degree captures the shape
(F ≥ 0.99), and selects the lowest clean degree within 0.01 of the best F-score. The paper's
rule (``"paper"``, Algorithm 1) stops when the smoothness gains less than ε. Every degree's
measures and the reason it was selected, rejected or not needed are in the result.
"""

import matplotlib.pyplot as plt

import ipfit

cloud = ipfit.load("airplane")
result = ipfit.fit_adaptive(cloud, max_degree=8, rng=0)
print(result.message)
print("degree  distance  smoothness  F-score  spurious")
for d in result.degrees:
    print(f"{d.degree:6d}  {d.distance:8.4f}  {d.measures.smoothness:10.4f}  {d.quality.f_score:7.3f}  "
          f"{d.quality.n_spurious:8d}")

# %%
# The smoothness path, the quantity of the paper's rule, with the selected degree marked.
fig, ax = plt.subplots(figsize=(5, 3))
ipfit.plot_smoothness([d.degree for d in result.degrees], [d.measures.smoothness for d in result.degrees],
                      selected=result.selected_degree, ax=ax)
plt.show()

# %%
# Every degree's fit; the selected one is framed.
fig = ipfit.plot_result(result, cloud.points)

# %%
# The reasons, as the JSON result and ``ipfit fit`` print them.
for d in result.degrees:
    print(f"degree {d.degree}: {d.reason}")
