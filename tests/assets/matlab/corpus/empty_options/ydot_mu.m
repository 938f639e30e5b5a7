function dy = ydot_mu(t,y,mu)
dy = [y(2); mu*(1-y(1)^2)*y(2)-y(1)];
