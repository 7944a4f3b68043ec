"""Stage 1 (fallen → kneel) by imitation: DAgger with the rise planner (training/planner/) as a closed-loop
teacher. The planner's rise is a knife edge that only its replanning holds, so behaviour cloning of its stored
rises drifts off them; here the learner's own states are labelled by short planner takeovers from them.

config.py  the settings;  expert.py  the batched takeovers (the labels);  learner.py  the policy network, its
fit and export;  dataset.py  the aggregated data on disk;  dagger.py  the rounds;  report.py  the campaign's
table and curve;  finetune.py  RL from the DAgger policy (PPO with a decaying BC term on the same data);
campaign.py  a
campaign's build and run;  __main__  `python -m training.imitation`."""
