"""What the simulator (sim_hil), training and the evaluations share, below all of them: the robot model and
scenario geometry, the observation layout, the policy artifact format, what fallen / standing / kneeling
mean (events), the loop's push test draw and the seed's published figures. Imports only `messages`."""
